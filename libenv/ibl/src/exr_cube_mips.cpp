// One tiled, mip-mapped OpenEXR cube file (exr_cube_mips.h), written with OpenEXR's TiledOutputFile.
#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfEnvmapAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfTileDescription.h>
#include <OpenEXR/ImfTiledInputFile.h>
#include <OpenEXR/ImfTiledOutputFile.h>
#include <envkit/core/error.h>
#include <envkit/ibl/exr_cube_mips.h>

#include <algorithm>
#include <exception>

namespace envkit {

namespace {

int floor_log2(int n) {
  int l = 0;
  while ((n >> (l + 1)) >= 1) ++l;
  return l;
}

// Level l of the file as OpenEXR sizes it: W_l x H_l image, face size min(W_l, H_l / 6).
struct LevelShape {
  int width, height, face;
};
LevelShape shape(int n, int l) {
  const int w = std::max(1, n >> l), h = std::max(1, (6 * n) >> l);
  return {w, h, std::min(w, h / 6)};
}

// The given level copied into a W_l x H_l image (padding rows 0).
Image placed(const Image& level, const LevelShape& s) {
  Image out(s.width, s.height, level.channels);
  out.channel_names = level.channel_names;
  std::copy(level.pixels.begin(), level.pixels.end(), out.pixels.begin());
  return out;
}

// Level l past the given ones, from level l - 1 (see exr_cube_mips.h).
Image reduced(const Image& prev, int prev_face, const LevelShape& s) {
  Image out(s.width, s.height, prev.channels);
  out.channel_names = prev.channel_names;
  const int c = prev.channels;
  if (s.face >= 1) {
    // Texel x of the smaller face averages the texels of the larger one its extent covers: [x r, (x + 1) r) with
    // r = prev_face / face, rounded outwards (2 x 2 for even sizes, 3 wide where an odd face halves).
    auto span = [&](int x, int& lo, int& hi) {
      lo = x * prev_face / s.face;
      hi = std::max(lo + 1, ((x + 1) * prev_face + s.face - 1) / s.face);
    };
    for (int f = 0; f < 6; ++f)
      for (int y = 0; y < s.face; ++y)
        for (int x = 0; x < s.face; ++x) {
          int x0, x1, y0, y1;
          span(x, x0, x1);
          span(y, y0, y1);
          for (int k = 0; k < c; ++k) {
            double sum = 0.0;
            for (int py = y0; py < y1; ++py)
              for (int px = x0; px < x1; ++px) sum += prev.at(px, f * prev_face + py, k);
            out.at(x, f * s.face + y, k) = float(sum / (double(y1 - y0) * (x1 - x0)));
          }
        }
    return out;
  }
  // No faces left: the mean of the six faces of the last level that has them (or of the previous faceless level,
  // which already holds that mean everywhere), everywhere.
  std::vector<double> mean(c, 0.0);
  const int rows = prev_face >= 1 ? 6 * prev_face : prev.height;
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < prev.width; ++x)
      for (int k = 0; k < c; ++k) mean[k] += prev.at(x, y, k);
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x)
      for (int k = 0; k < c; ++k) out.at(x, y, k) = float(mean[k] / (double(rows) * prev.width));
  return out;
}

}  // namespace

int exr_cube_mip_levels(int face_size) { return floor_log2(6 * face_size) + 1; }

ClampReport write_exr_cube_mips(const std::string& path, const std::vector<const Image*>& levels,
                                const ExrCubeMipsOptions& options) {
  if (levels.empty()) fail(path, "no levels to write");
  const int n = levels[0]->width;
  const int channels = levels[0]->channels;
  if (n < 1 || levels[0]->height != 6 * n) fail(path, "level 0 is not an N x 6N cube strip");
  if (channels < 1 || channels > 4) fail(path, "a cube level needs 1 to 4 channels");
  if (int(levels.size()) > floor_log2(n) + 1)
    fail(path, std::to_string(levels.size()) + " levels, but a cube of " + std::to_string(n) + " has at most " +
                   std::to_string(floor_log2(n) + 1));
  for (std::size_t m = 0; m < levels.size(); ++m) {
    const int s = std::max(1, n >> m);
    if (levels[m]->width != s || levels[m]->height != 6 * s || levels[m]->channels != channels ||
        levels[m]->channel_names != levels[0]->channel_names)
      fail(path, "level " + std::to_string(m) + " is not a " + std::to_string(s) + " x " + std::to_string(6 * s) +
                     " strip with the channels of level 0");
  }

  Imf::Header header(n, 6 * n);
  header.compression() = Imf::ZIP_COMPRESSION;
  header.setTileDescription(Imf::TileDescription(options.tile, options.tile, Imf::MIPMAP_LEVELS, Imf::ROUND_DOWN));
  Imf::addEnvmap(header, Imf::ENVMAP_CUBE);
  const Imf::PixelType pixel = options.half ? Imf::HALF : Imf::FLOAT;
  for (const std::string& name : levels[0]->channel_names) header.channels().insert(name, Imf::Channel(pixel));
  std::map<std::string, std::string> strings = options.attributes;
  strings["envkit:ibl_levels"] = std::to_string(levels.size());
  if (!strings.count("Software")) strings["Software"] = "envkit";
  for (const auto& [key, value] : strings) {
    if (header.find(key) != header.end()) fail(path, "attribute '" + key + "' is reserved");
    header.insert(key, Imf::StringAttribute(value));
  }

  ClampReport clamped;
  try {
    Imf::TiledOutputFile out(path.c_str(), header);
    if (out.numLevels() != exr_cube_mip_levels(n)) fail(path, "OpenEXR plans an unexpected number of levels");
    Image current;
    int current_face = 0;
    for (int l = 0; l < out.numLevels(); ++l) {
      const LevelShape s = shape(n, l);
      if (out.levelWidth(l) != s.width || out.levelHeight(l) != s.height)
        fail(path, "OpenEXR sizes level " + std::to_string(l) + " differently from the cube layout");
      current = l < int(levels.size()) ? placed(*levels[l], s) : reduced(current, current_face, s);
      current_face = s.face;
      // A tiled file takes slices of its channels' own type. Half data is converted here, clamped to half's
      // range (half() would give Inf beyond it), while the next reduced level still averages the exact values.
      std::vector<half> halves;
      if (options.half) {
        const std::span<const float> values(current.pixels.data(), current.pixels.size());
        clamped.add(count_clamped(values, channels, channels, kHalfRange));
        const auto largest = float(kHalfRange.max[0]);
        halves.reserve(values.size());
        for (float v : values) halves.emplace_back(std::clamp(v, -largest, largest));
      }
      char* base =
          options.half ? reinterpret_cast<char*>(halves.data()) : reinterpret_cast<char*>(current.pixels.data());
      const std::size_t element = options.half ? sizeof(half) : sizeof(float);
      Imf::FrameBuffer frame;
      const std::size_t xstride = element * channels, ystride = xstride * s.width;
      for (int c = 0; c < channels; ++c)
        frame.insert(current.channel_names[c], Imf::Slice(pixel, base + element * c, xstride, ystride));
      out.setFrameBuffer(frame);
      out.writeTiles(0, out.numXTiles(l) - 1, 0, out.numYTiles(l) - 1, l);
    }
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    fail(path, std::string("cannot write: ") + e.what());
  }
  return clamped;
}

std::optional<ExrLevels> read_exr_levels(const std::string& path) {
  try {
    ExrLevels out;
    Imf::InputFile probe(path.c_str());
    const Imf::Header& h = probe.header();
    const Imath::Box2i dw = h.dataWindow();
    if (!h.hasTileDescription() || h.tileDescription().mode == Imf::ONE_LEVEL) {
      out.sizes.emplace_back(dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1);
      return out;
    }
    Imf::TiledInputFile tiled(path.c_str());
    out.mode = tiled.levelMode() == Imf::MIPMAP_LEVELS ? "mipmap" : "ripmap";
    out.rounding = tiled.levelRoundingMode() == Imf::ROUND_DOWN ? "down" : "up";
    const int levels =
        tiled.levelMode() == Imf::MIPMAP_LEVELS ? tiled.numLevels() : std::min(tiled.numXLevels(), tiled.numYLevels());
    for (int l = 0; l < levels; ++l) out.sizes.emplace_back(tiled.levelWidth(l), tiled.levelHeight(l));
    return out;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace envkit
