#include "image_io_exr.h"

#include <OpenEXR/ImfBoxAttribute.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfChromaticitiesAttribute.h>
#include <OpenEXR/ImfCompressionAttribute.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFloatAttribute.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfRgbaFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>
#include <OpenEXR/openexr.h>
#include <envkit/core/error.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <vector>

namespace envkit::detail {
namespace {

bool has_exr_magic(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char m[4] = {};
  return in.read(reinterpret_cast<char*>(m), 4) && m[0] == 0x76 && m[1] == 0x2f && m[2] == 0x31 && m[3] == 0x01;
}

// The C++ library (3.1) allocates an attribute's value at the size its header claims, a preview at the width x
// height it claims, before reading either, and some typed readers ignore the stored size, so a 300-byte file can
// cost gigabytes before it fails. OpenEXR's C core parses the same header strictly (sizes against the file, types
// against their lengths) without such allocations: a header it refuses never reaches the C++ library.
void check_exr_header(const std::string& path) {
  struct Message {
    std::string text;
  } message;
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.user_data = &message;
  init.error_handler_fn = [](exr_const_context_t ctx, exr_result_t, const char* text) {
    void* user = nullptr;
    if (exr_get_user_data(ctx, &user) == EXR_ERR_SUCCESS && user && text && static_cast<Message*>(user)->text.empty())
      static_cast<Message*>(user)->text = text;
  };
  init.flags = EXR_CONTEXT_FLAG_STRICT_HEADER;
  exr_context_t ctx = nullptr;
  const exr_result_t rc = exr_start_read(&ctx, path.c_str(), &init);
  if (ctx) exr_finish(&ctx);
  // Even strict, the core reports a malformed optional attribute and goes on; the C++ library would not.
  if (rc != EXR_ERR_SUCCESS || !message.text.empty())
    fail(path, "corrupt OpenEXR header: " +
                   (message.text.empty() ? std::string(exr_get_default_error_message(rc)) : message.text));
}

/// Whether the channels are luminance and subsampled chroma (Y, RY, BY, maybe A, nothing else): what OpenEXR's RGBA
/// interface writes to save space, and reads back as R, G, B.
bool is_luminance_chroma(const Imf::ChannelList& list) {
  if (!list.findChannel("Y") || !list.findChannel("RY") || !list.findChannel("BY")) return false;
  for (auto it = list.begin(); it != list.end(); ++it)
    if (const std::string name = it.name(); name != "Y" && name != "RY" && name != "BY" && name != "A") return false;
  return true;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// Where a channel goes in OIIO's order: grouped by layer ("diffuse" in "diffuse.R", "" for "R", first), and within
/// a layer R, G, B, A (any case, also red/green/blue/alpha) first, then the others in the file's order.
struct ChannelKey {
  std::string layer;
  int rank = 4;
  bool operator<(const ChannelKey& other) const {
    return layer != other.layer ? layer < other.layer : rank < other.rank;
  }
};

ChannelKey channel_key(const std::string& name) {
  static const char* const first[][2] = {{"r", "red"}, {"g", "green"}, {"b", "blue"}, {"a", "alpha"}};
  const std::size_t dot = name.rfind('.');
  ChannelKey key;
  if (dot != std::string::npos) key.layer = name.substr(0, dot);
  const std::string suffix = lower(dot == std::string::npos ? name : name.substr(dot + 1));
  for (int i = 0; i < 4; ++i)
    if (suffix == first[i][0] || suffix == first[i][1]) key.rank = i;
  return key;
}

const char* compression_name(Imf::Compression c) {
  switch (c) {
    case Imf::NO_COMPRESSION:
      return "none";
    case Imf::RLE_COMPRESSION:
      return "rle";
    case Imf::ZIPS_COMPRESSION:
      return "zips";
    case Imf::ZIP_COMPRESSION:
      return "zip";
    case Imf::PIZ_COMPRESSION:
      return "piz";
    case Imf::PXR24_COMPRESSION:
      return "pxr24";
    case Imf::B44_COMPRESSION:
      return "b44";
    case Imf::B44A_COMPRESSION:
      return "b44a";
    case Imf::DWAA_COMPRESSION:
      return "dwaa";
    case Imf::DWAB_COMPRESSION:
      return "dwab";
    default:
      return "unknown";
  }
}

std::string number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

/// OIIO's names for OpenEXR's standard attributes.
std::string oiio_name(const std::string& exr) {
  if (exr == "comments") return "ImageDescription";
  if (exr == "owner") return "Copyright";
  if (exr == "capDate") return "DateTime";
  if (exr == "pixelAspectRatio") return "PixelAspectRatio";
  if (exr == "utcOffset") return "openexr:utcOffset";
  return exr;
}

}  // namespace

std::optional<FileSpec> read_exr_spec(const std::string& path) {
  if (!has_exr_magic(path)) return std::nullopt;
  check_exr_header(path);
  try {
    Imf::MultiPartInputFile file(path.c_str(), Imf::globalThreadCount());
    const Imf::Header& h = file.header(0);
    FileSpec f;
    f.format = "openexr";
    const std::string type = h.hasType() ? h.type() : std::string("scanlineimage");
    f.deep = type == "deepscanline" || type == "deeptile";
    const Imath::Box2i dw = h.dataWindow(), disp = h.displayWindow();
    // Sizes as 64-bit first: a hostile header can claim windows whose width overflows an int.
    const long long w = static_cast<long long>(dw.max.x) - dw.min.x + 1,
                    hh = static_cast<long long>(dw.max.y) - dw.min.y + 1;
    constexpr long long kMax = std::numeric_limits<int>::max();
    f.width = static_cast<int>(std::clamp(w, 0ll, kMax));
    f.height = static_cast<int>(std::clamp(hh, 0ll, kMax));
    f.x = dw.min.x, f.y = dw.min.y, f.full_x = disp.min.x, f.full_y = disp.min.y;
    f.full_width = static_cast<int>(std::clamp(static_cast<long long>(disp.max.x) - disp.min.x + 1, 0ll, kMax));
    f.full_height = static_cast<int>(std::clamp(static_cast<long long>(disp.max.y) - disp.min.y + 1, 0ll, kMax));
    struct Channel {
      std::string name;
      Imf::PixelType type;
      bool sampled;
    };
    std::vector<Channel> channels;
    for (auto it = h.channels().begin(); it != h.channels().end(); ++it)
      channels.push_back({it.name(), it.channel().type, it.channel().xSampling == 1 && it.channel().ySampling == 1});
    std::stable_sort(channels.begin(), channels.end(),
                     [](const Channel& a, const Channel& b) { return channel_key(a.name) < channel_key(b.name); });
    bool any_float = false, any_half = false, all_sampled = true;
    for (const Channel& c : channels) {
      f.channel_names.push_back(c.name);
      any_float = any_float || c.type == Imf::FLOAT;
      any_half = any_half || c.type == Imf::HALF;
      all_sampled = all_sampled && c.sampled;
      if (channel_key(c.name).rank == 3 && f.alpha_channel < 0)
        f.alpha_channel = static_cast<int>(f.channel_names.size()) - 1;
    }
    f.nchannels = static_cast<int>(channels.size());
    f.floating_point = any_float || any_half;
    f.pixel_type = any_float ? "float" : any_half ? "half" : "uint";
    f.format_bytes = any_float ? 4 : any_half ? 2 : 4;
    f.subsampled = !all_sampled;
    if (is_luminance_chroma(h.channels())) {
      f.luminance_chroma = true;
      f.subsampled = false;
      f.channel_names = {"R", "G", "B"};
      f.alpha_channel = -1;
      if (h.channels().findChannel("A")) {
        f.channel_names.push_back("A");
        f.alpha_channel = 3;
      }
      f.nchannels = static_cast<int>(f.channel_names.size());
      f.floating_point = true;
      f.pixel_type = "half";
      f.format_bytes = 2;
    }
    f.colorspace_tag = "Linear";
    for (auto it = h.begin(); it != h.end(); ++it) {
      const std::string name = it.name();
      const Imf::Attribute& a = it.attribute();
      if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&a))
        f.metadata[oiio_name(name)] = s->value();
      else if (const auto* i = dynamic_cast<const Imf::IntAttribute*>(&a))
        f.metadata[oiio_name(name)] = std::to_string(i->value());
      else if (const auto* fl = dynamic_cast<const Imf::FloatAttribute*>(&a))
        f.metadata[oiio_name(name)] = number(fl->value());
      else if (const auto* d = dynamic_cast<const Imf::DoubleAttribute*>(&a))
        f.metadata[oiio_name(name)] = number(d->value());
    }
    if (auto it = f.metadata.find("oiio:ColorSpace"); it != f.metadata.end()) f.colorspace_tag = it->second;
    f.metadata["oiio:ColorSpace"] = f.colorspace_tag;
    f.metadata["compression"] = compression_name(h.compression());
    if (const auto* c = h.findTypedAttribute<Imf::ChromaticitiesAttribute>("chromaticities")) {
      const Imf::Chromaticities& v = c->value();
      f.has_chromaticities = true;
      f.chromaticities = {v.red.x, v.red.y, v.green.x, v.green.y, v.blue.x, v.blue.y, v.white.x, v.white.y};
    }
    return f;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

bool exr_layout_supported(const FileSpec& spec) { return !spec.deep && !spec.subsampled; }

void read_exr_luminance_chroma(const std::string& path, const FileSpec& spec, float* pixels) {
  Imf::RgbaInputFile in(path.c_str(), Imf::globalThreadCount());
  const Imath::Box2i dw = in.dataWindow();
  // The buffer is sized from the spec: a file changed since its header was read must not write past it.
  if (dw.min.x != spec.x || dw.min.y != spec.y || dw.max.x - dw.min.x + 1 != spec.width ||
      dw.max.y - dw.min.y + 1 != spec.height)
    throw std::runtime_error("the data window changed while the file was read");
  const std::size_t width = static_cast<std::size_t>(spec.width), channels = static_cast<std::size_t>(spec.nchannels);
  std::vector<Imf::Rgba> rgba(width * static_cast<std::size_t>(spec.height));
  in.setFrameBuffer(rgba.data() - dw.min.x - static_cast<std::ptrdiff_t>(dw.min.y) * static_cast<std::ptrdiff_t>(width),
                    1, width);
  in.readPixels(dw.min.y, dw.max.y);
  tbb::parallel_for(0, spec.height, [&](int y) {
    const Imf::Rgba* from = rgba.data() + static_cast<std::size_t>(y) * width;
    float* to = pixels + static_cast<std::size_t>(y) * width * channels;
    for (std::size_t x = 0; x < width; ++x, to += channels) {
      to[0] = from[x].r;
      to[1] = from[x].g;
      to[2] = from[x].b;
      if (channels == 4) to[3] = from[x].a;
    }
  });
}

}  // namespace envkit::detail
