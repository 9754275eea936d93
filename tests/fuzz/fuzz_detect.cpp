// libFuzzer target: image -> parameterization detection, on small synthetic images and on raw image files.
//
// Input layout (bytes; missing bytes read as 0):
//   [0] mode: bits 0-1 select 0 = an Image built in memory, 1 = the rest written as .exr, 2 = .hdr, 3 = .pfm
//       (then read_image with small size limits: 1024 per side, 2^16 texels); bits 2-3 the resampling filter
//   [1] width - 1 (mod 48)   [2] height - 1 (mod 160)   [3] channels - 1 (mod 4; 2 and 4 have alpha last)
//   [4] --from: 0 none, 1..6 latlong, cube, mirrorball, angular, octahedral, paraboloid (mod 7)
//   [5] layout: 0 none, 1..4 vstrip, hstrip, hcross, vcross (mod 5)
//   [6] convention: 0 none, 1..6 envkit, openexr, hdrshop, angmap-cal, blender, gl (mod 7)
//   [7] [8] [9] ball centre x, y and radius: an index into kBallValues (8 or more: not given)
//   in-memory mode: then "key=value" lines up to a '\0' (Image::metadata: envkit:parameterization, envkit:layout,
//   envkit:convention, envmap, ...), then the pixels as raw little-endian floats (repeated to fill the image;
//   NaN, Inf, negative and denormal values included).
//   file modes: bytes [10..] are the file.
// On success the map's total power is computed and it is resampled to an 8x4 lat-long (and the reverse
// direction for a few texels), so the parameterization the detection produced is exercised, not just built.
// Every failure must be an envkit::Error whose message names the path (image_io.h: "<path>: <problem>");
// anything else is a finding (__builtin_trap after printing it).
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/latlong.h>
#include <envkit/resample/resample.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>

#include "fuzz_support.h"

namespace {

const char* const kKinds[] = {"latlong", "cube", "mirrorball", "angular", "octahedral", "paraboloid"};
const char* const kLayouts[] = {"vstrip", "hstrip", "hcross", "vcross"};
const char* const kConventions[] = {"envkit", "openexr", "hdrshop", "angmap-cal", "blender", "gl"};
const double kBallValues[] = {
    0.0, 3.5, 8.0, -2.0, 1e12, 0.25, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()};

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "FINDING: %s\n", what.c_str());
  std::fflush(stderr);
  __builtin_trap();
}

void exercise(const envkit::EnvMap& map, envkit::Filter filter) {
  const auto power = envkit::total_power(map.image, *map.param);
  (void)power;
  const envkit::LatLongMap out(8, 4);
  envkit::ResampleOptions ro;
  ro.filter = filter;
  const envkit::Image img = envkit::resample(map.ref(), out, envkit::identity3(), ro);
  if (img.width != 8 || img.height != 4) finding("resample returned a wrong size");
  for (int j = 0; j < map.image.height; j += 3)
    for (int i = 0; i < map.image.width; i += 3) {
      envkit::Vec3 d;
      if (map.param->to_direction(envkit::Vec2(i + 0.5, j + 0.5), d)) (void)map.param->to_image(d);
    }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  envkit::fuzz::run_on_one_thread();
  ::unsetenv("OCIO");
  ::unsetenv("ENVKIT_OCIO_CONFIG");
  envkit::fuzz::scratch_dir("detect");
  envkit::fuzz::leave_signals_to_libfuzzer();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto byte = [&](std::size_t i) -> unsigned { return i < size ? data[i] : 0u; };
  const unsigned mode = byte(0) & 3u;
  const envkit::Filter filter = static_cast<envkit::Filter>((byte(0) >> 2) & 3u);
  envkit::LoadOptions opt;
  if (byte(4) % 7) opt.kind = envkit::parse_kind(kKinds[byte(4) % 7 - 1]);
  if (byte(5) % 5) opt.layout = envkit::parse_layout(kLayouts[byte(5) % 5 - 1]);
  if (byte(6) % 7) opt.convention = &envkit::convention(kConventions[byte(6) % 7 - 1]);
  if (byte(7) < 8) opt.ball_cx = kBallValues[byte(7)];
  if (byte(8) < 8) opt.ball_cy = kBallValues[byte(8)];
  if (byte(9) < 8) opt.ball_radius = kBallValues[byte(9)];
  opt.read.max_side = 1024;
  opt.read.max_texels = 1 << 16;
  opt.read.nonfinite = static_cast<envkit::NonFinitePolicy>(byte(3) >> 6 == 3 ? 0 : byte(3) >> 6);

  std::string path = "mem.exr";
  envkit::Image image;
  std::size_t pos = 10;
  if (mode == 0) {
    const int w = 1 + int(byte(1) % 48), h = 1 + int(byte(2) % 160), c = 1 + int(byte(3) % 4);
    image = envkit::Image(w, h, c);
    image.channel_names = envkit::default_channel_names(c);
    if (c == 2 || c == 4) image.alpha_channel = c - 1;
    std::string line;
    for (; pos < size && data[pos] != 0; ++pos) {
      if (data[pos] == '\n') {
        const auto eq = line.find('=');
        if (eq != std::string::npos) image.metadata[line.substr(0, eq)] = line.substr(eq + 1);
        line.clear();
      } else {
        line += static_cast<char>(data[pos]);
      }
    }
    const auto eq = line.find('=');
    if (eq != std::string::npos) image.metadata[line.substr(0, eq)] = line.substr(eq + 1);
    ++pos;
    const std::size_t nbytes = pos < size ? size - pos : 0;
    if (nbytes >= 4) {
      const std::size_t nfloats = nbytes / 4;
      for (std::size_t k = 0; k < image.pixels.size(); ++k)
        std::memcpy(&image.pixels[k], data + pos + 4 * (k % nfloats), 4);
    }
  } else {
    // Formats envkit decodes itself or through OpenEXR (whose header it checks first): the file starts with its
    // format's magic, written here when the input lacks it. Arbitrary bytes would otherwise reach OIIO's other
    // plugins and libpng, whose allocations on hostile headers envkit cannot bound (seconds and gigabytes a unit).
    static const char* const ext[] = {"", ".exr", ".hdr", ".pfm"};
    static const std::string magic[] = {"", "\x76\x2f\x31\x01", "#?", "PF\n"};
    path = (envkit::fuzz::scratch_dir() / (std::string("input") + ext[mode])).string();
    {
      std::ofstream f(path, std::ios::binary | std::ios::trunc);
      const std::string body(reinterpret_cast<const char*>(data) + std::min(pos, size), size - std::min(pos, size));
      const bool pfm =
          body.size() >= 3 && body[0] == 'P' && (body[1] == 'F' || body[1] == 'f') && std::isspace(body[2]);
      if (mode == 3 ? !pfm : body.compare(0, magic[mode].size(), magic[mode]) != 0) f << magic[mode];
      f << body;
    }
    try {
      envkit::ReadReport report;
      image = envkit::read_image(path, opt.read, &report);
    } catch (const envkit::Error& e) {
      if (std::string(e.what()).find(path) == std::string::npos)
        finding(std::string("read_image error does not name the file: ") + e.what());
      return 0;
    } catch (const std::exception& e) {
      finding(std::string("read_image threw a non-envkit exception: ") + e.what());
    }
    if (image.width < 1 || image.height < 1 || image.channels < 1 || image.channels > 4 ||
        image.pixels.size() != image.texel_count() * image.channels)
      finding("read_image returned an inconsistent image");
    if (opt.read.nonfinite != envkit::NonFinitePolicy::Error)
      for (float v : image.pixels)
        if (!std::isfinite(v)) finding("a non-finite value survived the non-finite policy");
  }

  envkit::EnvMap map;
  try {
    envkit::Detection detection;
    map = envkit::make_envmap(std::move(image), path, opt, &detection);
  } catch (const envkit::Error& e) {
    if (std::getenv("ENVKIT_FUZZ_STRICT") && std::string(e.what()).find(path) == std::string::npos)
      finding(std::string("detection error does not name the file: ") + e.what());
    return 0;
  } catch (const std::exception& e) {
    finding(std::string("make_envmap threw a non-envkit exception: ") + e.what());
  }
  try {
    exercise(map, filter);
  } catch (const envkit::Error&) {
    // Maps the detection accepted should resample, but an Error is a clean refusal, not a crash.
  }
  return 0;
}
