#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfChromaticitiesAttribute.h>
#include <OpenEXR/ImfEnvmapAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfThreading.h>
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/core/huge_page_allocator.h>
#include <envkit/core/input_checks.h>
#include <envkit/io/color.h>
#include <envkit/io/image_codecs.h>
#include <envkit/io/image_io.h>
#include <envkit/io/oiio_env_tags.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <thread>

#include "image_backend.h"
#include "image_io_exr.h"
#include "image_io_native.h"

namespace envkit {
namespace fs = std::filesystem;

namespace {

// ---- small helpers ---------------------------------------------------------------------------------------

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

/// Library messages can span lines and name envkit's temp file; users get one line naming their path.
std::string condense(std::string text, const std::string& temp = "", const std::string& target = "") {
  if (!temp.empty() && temp != target)  // equal when a writer was handed a temp path (see atomic_file.h)
    for (std::size_t pos = text.find(temp); pos != std::string::npos; pos = text.find(temp, pos + target.size()))
      text.replace(pos, temp.size(), target);
  for (char& c : text)
    if (c == '\n' || c == '\r' || c == '\t') c = ' ';
  std::string out;
  for (char c : text)
    if (!(c == ' ' && (out.empty() || out.back() == ' '))) out += c;
  while (!out.empty() && out.back() == ' ') out.pop_back();
  return out.empty() ? "unknown error" : out;
}

// ---- OpenEXR ------------------------------------------------------------------------------------------------

/// OpenEXR's thread pool (de)compresses blocks in parallel: it is empty until sized, and the threads
/// argument of Imf::OutputFile only sets the number of line buffers. Sized once, to the machine.
void use_exr_threads() {
  static const bool once = [] {
    Imf::setGlobalThreadCount(static_cast<int>(std::max(1u, std::thread::hardware_concurrency())));
    return true;
  }();
  (void)once;
}

// ---- non-finite values -------------------------------------------------------------------------------------

using Range = tbb::blocked_range<std::size_t>;
constexpr std::size_t kGrain = 1 << 16;
/// Rows of half data an EXR write converts at a time: enough for every thread's line buffers, small enough to stay
/// in memory already touched.
constexpr std::size_t kHalfBlockBytes = std::size_t(16) << 20;

}  // namespace

namespace {

/// NaN, +/-Inf and values below zero among `values`. The common case, a block without a non-finite value, takes one
/// loop without branches (the compiler vectorises it); a block that holds one is classified value by value.
struct ValueCounts {
  NonFiniteCounts nonfinite;
  std::size_t negative = 0;
  ValueCounts operator+(const ValueCounts& o) const { return {nonfinite + o.nonfinite, negative + o.negative}; }
};

ValueCounts count_block(const float* v, std::size_t n) {
  ValueCounts counts;
  constexpr std::size_t kBlock = 4096;  // 32-bit counters per block: lanes the vector loop can use
  for (std::size_t start = 0; start < n; start += kBlock) {
    const std::size_t m = std::min(kBlock, n - start);
    const float* b = v + start;
    std::uint32_t negative = 0, nonfinite = 0;
    for (std::size_t i = 0; i < m; ++i) {
      negative += b[i] < 0.0f ? 1u : 0u;
      nonfinite += std::abs(b[i]) <= FLT_MAX ? 0u : 1u;  // false for NaN and +/-Inf
    }
    counts.negative += negative;
    if (nonfinite == 0) continue;
    for (std::size_t i = 0; i < m; ++i) {
      if (std::isnan(b[i]))
        ++counts.nonfinite.nan;
      else if (std::isinf(b[i]))
        ++(b[i] > 0 ? counts.nonfinite.posinf : counts.nonfinite.neginf);
    }
  }
  return counts;
}

ValueCounts count_values(std::span<const float> values) {
  return tbb::parallel_reduce(
      Range(0, values.size(), kGrain), ValueCounts{},
      [&](const Range& r, ValueCounts acc) { return acc + count_block(values.data() + r.begin(), r.size()); },
      std::plus<>());
}

}  // namespace

NonFiniteCounts count_nonfinite(std::span<const float> values) { return count_values(values).nonfinite; }

namespace {

std::size_t count_negative(std::span<const float> values) { return count_values(values).negative; }

/// Largest finite value of each channel (0 for a channel without finite values).
std::vector<float> channel_max_finite(const Image& image) {
  const auto nc = static_cast<std::size_t>(image.channels);
  using Maxes = std::vector<float>;
  const Maxes lowest(nc, -std::numeric_limits<float>::infinity());
  Maxes m = tbb::parallel_reduce(
      Range(0, image.texel_count(), kGrain / 4), lowest,
      [&](const Range& r, Maxes acc) {
        for (std::size_t t = r.begin(); t != r.end(); ++t)
          for (std::size_t c = 0; c < nc; ++c) {
            const float v = image.pixels[t * nc + c];
            if (std::isfinite(v)) acc[c] = std::max(acc[c], v);
          }
        return acc;
      },
      [](Maxes a, const Maxes& b) {
        for (std::size_t c = 0; c < a.size(); ++c) a[c] = std::max(a[c], b[c]);
        return a;
      });
  for (float& v : m)
    if (!std::isfinite(v)) v = 0.0f;
  return m;
}

void apply_nonfinite_policy(Image& image, NonFinitePolicy policy) {
  const std::vector<float> maxes = policy == NonFinitePolicy::Clamp ? channel_max_finite(image) : std::vector<float>{};
  const auto nc = static_cast<std::size_t>(image.channels);
  tbb::parallel_for(Range(0, image.pixels.size(), kGrain), [&](const Range& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      float& v = image.pixels[i];
      if (std::isfinite(v)) continue;
      v = (policy == NonFinitePolicy::Clamp && std::isinf(v) && v > 0) ? maxes[i % nc] : 0.0f;
    }
  });
}

// ---- reading: header checks, layout, colour space ----------------------------------------------------------

/// Size checks every reader makes on the header, before pixel memory is allocated.
void check_dimensions(const std::string& path, int width, int height, int channels, const ReadOptions& options) {
  if (width <= 0 || height <= 0 || channels <= 0)
    fail(path, "zero-size image (" + std::to_string(width) + "x" + std::to_string(height) + ", " +
                   std::to_string(channels) + " channels)");
  const std::string size = std::to_string(width) + "x" + std::to_string(height);
  if (width > options.max_side || height > options.max_side)
    fail(path, "image too large: " + size + " (envkit reads at most " + std::to_string(options.max_side) +
                   " pixels per side)");
  const std::int64_t texels = std::int64_t(width) * std::int64_t(height);
  if (texels > options.max_texels)
    fail(path, "image too large: " + size + " = " + std::to_string(texels) + " texels (limit " +
                   std::to_string(options.max_texels) + ")");
  if (channels > 4)
    fail(path,
         "unsupported channel count " + std::to_string(channels) + " (envkit reads 1 to 4 channels: Y, YA, RGB, RGBA)");
  // The float pixels, plus one more image of the same size for the conversions that follow a read.
  const std::uint64_t bytes = std::uint64_t(texels) * std::uint64_t(channels) * sizeof(float);
  check_memory_for(path, "image too large: " + size + " (" + std::to_string(channels) + " channels, float)", bytes);
}

void check_header(const std::string& path, const detail::FileSpec& spec, const ReadOptions& options) {
  if (spec.deep) fail(path, "deep images are not supported");
  if (spec.depth > 1) fail(path, "volume images (depth " + std::to_string(spec.depth) + ") are not supported");
  check_dimensions(path, spec.width, spec.height, spec.nchannels, options);
}

int find_alpha(const detail::FileSpec& spec) {
  if (spec.alpha_channel >= 0 && spec.alpha_channel < spec.nchannels) return spec.alpha_channel;
  for (int c = 0; c < spec.nchannels; ++c) {
    const std::string name = lower(spec.channel_names[static_cast<std::size_t>(c)]);
    if (name == "a" || name == "alpha") return c;
  }
  // envkit's layouts are Y, YA, RGB, RGBA: a second or fourth channel is coverage.
  return (spec.nchannels == 2 || spec.nchannels == 4) ? spec.nchannels - 1 : -1;
}

/// Moves the alpha channel (if any, and not already last) to the end, keeping colour channels in order.
void move_alpha_last(Image& image) {
  const int a = image.alpha_channel;
  const int last = image.channels - 1;
  if (a < 0 || a == last) return;
  const auto nc = static_cast<std::size_t>(image.channels);
  tbb::parallel_for(Range(0, image.texel_count(), kGrain / 4), [&](const Range& r) {
    for (std::size_t t = r.begin(); t != r.end(); ++t) {
      float* px = &image.pixels[t * nc];
      std::rotate(px + a, px + a + 1, px + nc);
    }
  });
  std::rotate(image.channel_names.begin() + a, image.channel_names.begin() + a + 1, image.channel_names.end());
  image.alpha_channel = last;
}

bool is_eight_bit(const detail::FileSpec& spec) {
  const int bits = spec.bits_per_sample;
  return (bits > 0 && bits <= 8) || spec.format_bytes == 1;
}

/// How to decode the file's pixels to the working space.
struct Decoding {
  std::string colorspace;  // canonical OCIO name, or empty when decoding a bare gamma
  double gamma = 0.0;      // > 0: pure power-law decode
  std::string reason;
};

std::optional<double> parse_gamma_tag(const std::string& tag, const detail::FileSpec& spec) {
  const std::string t = lower(tag);
  if (t == "gammacorrected") return spec.gamma;
  if (t.rfind("gamma", 0) == 0) {
    try {
      const double g = std::stod(t.substr(5));
      if (g > 0.0 && std::isfinite(g)) return g;
    } catch (const std::exception&) {
    }
  }
  return std::nullopt;
}

/// OpenEXR chromaticities (Rx Ry Gx Gy Bx By Wx Wy) of well-known linear spaces.
std::string colorspace_from_chromaticities(const detail::FileSpec& spec) {
  if (!spec.has_chromaticities) return "";
  const float* c = spec.chromaticities.data();
  struct Known {
    const char* name;
    std::array<float, 8> xy;
  };
  static const Known known[] = {
      {"lin_rec709", {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f}},
      {"acescg", {0.713f, 0.293f, 0.165f, 0.830f, 0.128f, 0.044f, 0.32168f, 0.33767f}},
      {"aces2065-1", {0.7347f, 0.2653f, 0.0f, 1.0f, 0.0001f, -0.077f, 0.32168f, 0.33767f}},
      {"lin_p3d65", {0.680f, 0.320f, 0.265f, 0.690f, 0.150f, 0.060f, 0.3127f, 0.3290f}},
      {"lin_rec2020", {0.708f, 0.292f, 0.170f, 0.797f, 0.131f, 0.046f, 0.3127f, 0.3290f}},
  };
  for (const Known& k : known) {
    bool match = true;
    for (int i = 0; i < 8; ++i) match = match && std::abs(c[i] - k.xy[static_cast<std::size_t>(i)]) < 2e-3f;
    if (match) return k.name;
  }
  return "?";
}

/// Canonical name of `name` in the active config, or "" (never throws for unknown names).
std::string known_colorspace(const std::string& name) {
  try {
    return canonical_colorspace(name);
  } catch (const Error&) {
    return "";
  }
}

/// True if a colour-space tag names a transfer-encoded (non-linear) space.
bool tag_is_encoded(const std::string& tag, const detail::FileSpec& spec) {
  if (parse_gamma_tag(tag, spec)) return true;
  const std::string cs = known_colorspace(tag);
  return !cs.empty() && (cs == known_colorspace("srgb") || cs == known_colorspace("rec709"));
}

Decoding decide_decoding(const detail::FileSpec& spec, const std::string& format, const ReadOptions& options,
                         ReadReport& report) {
  if (!options.colorspace.empty()) return {canonical_colorspace(options.colorspace), 0.0, "option"};
  const bool integer = !spec.floating_point;
  const bool eight_bit = integer && is_eight_bit(spec);
  if (integer && format == "openexr") {
    // OpenEXR's UINT channels hold ids and counts, not encoded colour.
    if (std::string raw = known_colorspace("raw"); !raw.empty()) return {raw, 0.0, "OpenEXR integer channels are data"};
  }
  std::string tag = spec.colorspace_tag;
  static const std::set<std::string> linear_tags = {"linear", "lin_srgb", "lin_rec709", "scene_linear", "scene-linear"};
  const bool tag_is_linear = linear_tags.count(lower(tag)) > 0;

  if (!integer && !tag.empty() && !tag_is_linear && tag_is_encoded(tag, spec)) {
    // Float formats hold linear light. OIIO tags every PNM file (PFM included) "Rec709" by default.
    if (format != "pnm") report.notes.push_back("float data tagged " + tag + ": taken as linear");
    tag.clear();
  }
  const std::string why_tag = "file tag oiio:ColorSpace=" + tag;
  if (!tag.empty() && !tag_is_linear) {
    if (auto g = parse_gamma_tag(tag, spec)) return {"", *g, why_tag};
    if (std::string cs = known_colorspace(tag); !cs.empty()) return {cs, 0.0, why_tag};
    report.notes.push_back("unknown colour-space tag '" + tag + "' ignored");
  }
  if (eight_bit) {
    if (tag_is_linear)
      report.notes.push_back("8-bit data tagged " + tag + ": decoded as sRGB (8 bits cannot hold linear light)");
    return {canonical_colorspace("srgb"), 0.0, "default for 8-bit data"};
  }
  if (!integer) {
    const std::string chroma = colorspace_from_chromaticities(spec);
    if (chroma == "?") {
      report.notes.push_back("unrecognised chromaticities attribute ignored: working-space primaries assumed");
    } else if (!chroma.empty()) {
      if (std::string cs = known_colorspace(chroma); !cs.empty()) return {cs, 0.0, "file chromaticities"};
      report.notes.push_back("chromaticities match " + chroma + ", which the OCIO config lacks: working space assumed");
    }
  }
  if (tag_is_linear) return {working_space(), 0.0, why_tag};
  if (integer) return {canonical_colorspace("srgb"), 0.0, "default for integer data"};
  return {working_space(), 0.0, "default for float data"};
}

/// "latlong" / "cube" from OpenEXR's typed envmap attribute of part 0, or "".
/// Read with OpenEXR itself: OIIO reports it as a "textureformat" string, which a stale string attribute of
/// the same name (OIIO writes one; exrenvmap copies it into its outputs) can contradict.
std::string exr_envmap(const std::string& path) {
  try {
    Imf::MultiPartInputFile file(path.c_str());
    if (const auto* a = file.header(0).findTypedAttribute<Imf::EnvmapAttribute>("envmap"))
      return a->value() == Imf::ENVMAP_CUBE ? "cube" : "latlong";
  } catch (const std::exception&) {
    // The pixels were read already; an unreadable header here only means "no envmap".
  }
  return "";
}

std::unique_ptr<detail::BackendInput> open_input(const std::string& path) {
  std::string error;
  bool unknown = false;
  auto in = detail::backend_for_reading(path).open(path, error, unknown);
  if (!in) {
    if (unknown) fail(path, "unknown image format (no OpenImageIO reader recognises it)");
    fail(path, "cannot read: " + condense(error));
  }
  return in;
}

// ---- writing --------------------------------------------------------------------------------------------------

struct Target {
  std::string format;  // OIIO format name, or "pfm" (envkit's own writer)
  bool alpha = true;   // the format stores alpha
  bool float_ok = false;
  bool half_ok = false;
  bool uint16_ok = false;
  bool rgb_only = false;  // HDR: exactly 3 channels
};

Target describe_target(const std::string& path) {
  const std::string ext = lower(fs::path(path).extension().string());
  if (ext == ".pfm") return {"pfm", false, true, false, false, false};
  if (ext == ".hdr" || ext == ".rgbe" || ext == ".pic") return {"hdr", false, true, false, false, true};
  if (ext.empty()) fail(path, "no file extension: cannot tell which image format to write");
  if (ext == ".exr" || ext == ".sxr" || ext == ".mxr") return {"openexr", true, true, true, false, false};
  detail::WriterInfo info;
  if (!detail::backend_for_writing(path).writer_for(path, info))
    fail(path, "unknown image format '" + ext + "' (no OpenImageIO writer for it)");
  Target t;
  t.format = info.format;
  t.alpha = info.alpha;
  t.float_ok = t.format == "openexr" || t.format == "tiff" || t.format == "hdr";
  t.half_ok = t.format == "openexr";
  t.uint16_ok = t.format == "png" || t.format == "tiff" || t.format == "pnm";
  t.rgb_only = t.format == "hdr";
  return t;
}

/// Resolves PixelType::Auto and rejects combinations the format cannot store.
PixelType choose_pixel_type(const std::string& path, const Target& t, PixelType requested) {
  if (requested == PixelType::Auto) return t.float_ok ? PixelType::Float : PixelType::UInt8;
  const bool ok = (requested == PixelType::Float && t.float_ok) || (requested == PixelType::Half && t.half_ok) ||
                  (requested == PixelType::UInt8 && !t.float_ok) ||
                  (requested == PixelType::UInt8 && t.format == "tiff") ||
                  (requested == PixelType::UInt16 && t.uint16_ok);
  if (!ok) {
    static const char* names[] = {"auto", "half", "float", "uint8", "uint16"};
    fail(path,
         std::string("the ") + t.format + " format cannot store " + names[static_cast<int>(requested)] + " pixels");
  }
  return requested;
}

void check_writable_image(const std::string& path, const Image& image) {
  if (image.empty()) fail(path, "cannot write an empty image");
  if (image.channels > 4)
    fail(path, "cannot write " + std::to_string(image.channels) + " channels (envkit writes 1 to 4)");
  if (image.pixels.size() != image.texel_count() * static_cast<std::size_t>(image.channels))
    fail(path, "pixel buffer size does not match " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                   "x" + std::to_string(image.channels));
  const NonFiniteCounts bad = count_nonfinite(image.pixels);
  if (const std::size_t n = bad.nan + bad.posinf + bad.neginf; n > 0)
    fail(path, "image has " + std::to_string(n) + " non-finite values (" + std::to_string(bad.nan) + " NaN, " +
                   std::to_string(bad.posinf + bad.neginf) + " Inf); refusing to write");
}

/// The image reduced/expanded to what the format stores: colour channels (Y replicated to RGB when the
/// format needs RGB), then alpha if the format keeps it.
/// True when select_channels would return a verbatim copy (same channels, same order, same names).
bool writes_channels_as_they_are(const Image& image, const Target& t) {
  if (t.rgb_only) return false;
  if (image.alpha_channel >= 0 && (!t.alpha || image.alpha_channel != image.channels - 1)) return false;
  if (image.channel_names.size() != static_cast<std::size_t>(image.channels)) return false;
  return std::none_of(image.channel_names.begin(), image.channel_names.end(),
                      [](const std::string& n) { return n.empty(); });
}

Image select_channels(const Image& image, const Target& t) {
  std::vector<int> colour;
  for (int c = 0; c < image.channels; ++c)
    if (c != image.alpha_channel) colour.push_back(c);
  const bool expand = t.rgb_only && colour.size() == 1;
  const bool keep_alpha = image.alpha_channel >= 0 && t.alpha && !t.rgb_only;
  std::vector<int> src = expand ? std::vector<int>{colour[0], colour[0], colour[0]} : colour;
  if (keep_alpha) src.push_back(image.alpha_channel);

  Image out;
  out.width = image.width;
  out.height = image.height;
  out.channels = static_cast<int>(src.size());
  out.alpha_channel = keep_alpha ? out.channels - 1 : -1;
  const bool names_ok = image.channel_names.size() == static_cast<std::size_t>(image.channels);
  if (expand) {
    out.channel_names = {"R", "G", "B"};
  } else {
    for (int c : src) out.channel_names.push_back(names_ok ? image.channel_names[static_cast<std::size_t>(c)] : "");
    const auto defaults = default_channel_names(out.channels);
    for (std::size_t c = 0; c < out.channel_names.size(); ++c)
      if (out.channel_names[c].empty()) out.channel_names[c] = defaults[c];
  }
  out.pixels.resize(out.texel_count() * src.size());
  const auto in_nc = static_cast<std::size_t>(image.channels);
  const std::size_t out_nc = src.size();
  tbb::parallel_for(Range(0, out.texel_count(), kGrain / 4), [&](const Range& r) {
    for (std::size_t t2 = r.begin(); t2 != r.end(); ++t2)
      for (std::size_t c = 0; c < out_nc; ++c)
        out.pixels[t2 * out_nc + c] = image.pixels[t2 * in_nc + static_cast<std::size_t>(src[c])];
  });
  return out;
}

/// Associated <-> unassociated alpha, in linear light. Unpremultiplying a zero-alpha texel gives colour 0.
void multiply_alpha(Image& image, bool divide) {
  const int a = image.alpha_channel;
  if (a < 0) return;
  const auto nc = static_cast<std::size_t>(image.channels);
  tbb::parallel_for(Range(0, image.texel_count(), kGrain / 4), [&](const Range& r) {
    for (std::size_t t = r.begin(); t != r.end(); ++t) {
      float* px = &image.pixels[t * nc];
      const float alpha = px[a];
      for (std::size_t c = 0; c < nc; ++c) {
        if (static_cast<int>(c) == a) continue;
        px[c] = divide ? (alpha > 0.0f ? px[c] / alpha : 0.0f) : px[c] * alpha;
      }
    }
  });
}

void clamp_all(Image& image, float lo, float hi) {
  tbb::parallel_for(Range(0, image.pixels.size(), kGrain), [&](const Range& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) image.pixels[i] = std::clamp(image.pixels[i], lo, hi);
  });
}

bool carried_metadata_key(const std::string& key) {
  static const std::set<std::string> descriptive = {"ImageDescription", "Copyright", "Artist", "DateTime", "owner",
                                                    "comments",         "capDate"};
  return key.rfind("envkit:", 0) == 0 || descriptive.count(key) > 0;
}

/// The colour space integer pixels are encoded to: the option, else sRGB, or Rec.709 for Netpbm files
/// (the transfer that format specifies, and what OIIO tags them with on reading).
std::string encode_colorspace_for(const Target& t, const WriteOptions& options) {
  if (!options.encode_colorspace.empty()) return options.encode_colorspace;
  return t.format == "pnm" ? "rec709" : "srgb";
}

detail::WriteSpec make_spec(const Image& data, const Target& t, PixelType type, const Image& source,
                            const WriteOptions& options) {
  detail::WriteSpec spec;
  spec.width = data.width, spec.height = data.height, spec.channels = data.channels;
  spec.pixel_type = type == PixelType::Half     ? "half"
                    : type == PixelType::UInt8  ? "uint8"
                    : type == PixelType::UInt16 ? "uint16"
                                                : "float";
  spec.channel_names = data.channel_names;
  spec.alpha_channel = data.alpha_channel;

  std::string compression = options.compression;
  if (compression.empty() && t.format == "tiff") compression = "zip";
  if (compression.empty() && t.format == "jpeg") compression = "jpeg:95";
  if (!compression.empty()) spec.attributes.emplace_back("compression", compression);

  const bool encoded = type == PixelType::UInt8 || type == PixelType::UInt16;
  if (encoded && canonical_colorspace(encode_colorspace_for(t, options)) == canonical_colorspace("srgb"))
    spec.attributes.emplace_back("oiio:ColorSpace",
                                 "sRGB");  // PNG writes its sRGB chunk, TIFF/JPEG readers decode right
  spec.unassociated_alpha = encoded && data.alpha_channel >= 0;  // already divided

  std::map<std::string, std::string> strings;
  for (const auto& [key, value] : source.metadata)
    if (carried_metadata_key(key)) strings[key] = value;
  for (const auto& [key, value] : options.metadata) strings[key] = value;
  if (!strings.count("Software")) strings["Software"] = "envkit";
  for (const auto& [key, value] : strings) spec.attributes.emplace_back(key, value);
  return spec;
}

void check_envmap_option(const std::string& path, const Image& image, const Target& t, const std::string& envmap) {
  if (envmap.empty()) return;
  if (envmap != "latlong" && envmap != "cube")
    fail(path, "unknown envmap attribute '" + envmap + "' (use latlong or cube)");
  if (t.format != "openexr") fail(path, "the envmap attribute needs an OpenEXR (.exr) file");
  if (envmap == "cube" && image.height != 6 * image.width)
    fail(path, "an OpenEXR cube map is one N x 6N image; got " + std::to_string(image.width) + "x" +
                   std::to_string(image.height));
}

const std::map<std::string, Imf::Compression>& exr_compressions() {
  static const std::map<std::string, Imf::Compression> names = {
      {"none", Imf::NO_COMPRESSION},  {"rle", Imf::RLE_COMPRESSION},   {"zips", Imf::ZIPS_COMPRESSION},
      {"zip", Imf::ZIP_COMPRESSION},  {"piz", Imf::PIZ_COMPRESSION},   {"pxr24", Imf::PXR24_COMPRESSION},
      {"b44", Imf::B44_COMPRESSION},  {"b44a", Imf::B44A_COMPRESSION}, {"dwaa", Imf::DWAA_COMPRESSION},
      {"dwab", Imf::DWAB_COMPRESSION}};
  return names;
}

std::string exr_compression_base(const std::string& name) { return lower(name.substr(0, name.find(':'))); }

Imf::Compression exr_compression(const std::string& path, const std::string& name, float& dwa_level) {
  const std::string base = exr_compression_base(name);
  const auto it = exr_compressions().find(base.empty() ? "zip" : base);
  if (it == exr_compressions().end())
    fail(path, "unknown OpenEXR compression '" + name + "' (" + exr_compression_list() + ")");
  if (const auto colon = name.find(':'); colon != std::string::npos && (base == "dwaa" || base == "dwab")) {
    try {
      dwa_level = std::stof(name.substr(colon + 1));
    } catch (const std::exception&) {
      fail(path, "bad DWA compression level in '" + name + "'");
    }
  }
  return it->second;
}

/// OIIO's names for the standard descriptive attributes, and OpenEXR's (what OIIO maps them to on reading).
std::string exr_attribute_name(const std::string& key) {
  if (key == "ImageDescription") return "comments";
  if (key == "Copyright") return "owner";
  if (key == "DateTime") return "capDate";
  return key;
}

/// OpenEXR files are written with the OpenEXR library itself: the envmap attribute must be OpenEXR's typed
/// attribute. OIIO 2.4 can produce it (textureformat hint) but also stores a "textureformat" string that
/// tools copying attributes (exrenvmap) carry into files where it contradicts the typed one.
void write_exr(const std::string& path, const std::string& file, const Image& data, PixelType type, const Image& source,
               const WriteOptions& options) {
  Imf::Header header(data.width, data.height);
  float dwa_level = header.dwaCompressionLevel();
  header.compression() = exr_compression(path, options.compression, dwa_level);
  header.dwaCompressionLevel() = dwa_level;
  const Imf::PixelType pixel = type == PixelType::Half ? Imf::HALF : Imf::FLOAT;
  for (const std::string& name : data.channel_names) header.channels().insert(name, Imf::Channel(pixel));
  if (!options.envmap_attribute.empty())
    header.insert("envmap",
                  Imf::EnvmapAttribute(options.envmap_attribute == "cube" ? Imf::ENVMAP_CUBE : Imf::ENVMAP_LATLONG));
  // Tag the primaries when the working space is envkit's (Imf::Chromaticities() is Rec.709 / D65).
  if (working_space() == known_colorspace("lin_rec709"))
    header.insert("chromaticities", Imf::ChromaticitiesAttribute(Imf::Chromaticities()));

  std::map<std::string, std::string> strings;
  for (const auto& [key, value] : source.metadata)
    if (carried_metadata_key(key)) strings[exr_attribute_name(key)] = value;
  for (const auto& [key, value] : options.metadata) strings[exr_attribute_name(key)] = value;
  if (!strings.count("Software")) strings["Software"] = "envkit";
  for (const auto& [key, value] : strings) {
    if (header.find(key) != header.end()) {
      if (!header.findTypedAttribute<Imf::StringAttribute>(key))
        fail(path, "metadata key '" + key + "' is a reserved OpenEXR attribute");
    }
    // OIIO's texture system reads oiio:sampleborder with get_int_attribute: store it as an integer.
    if (is_oiio_int_tag(key)) {
      header.insert(key, Imf::IntAttribute(std::atoi(value.c_str())));
      continue;
    }
    header.insert(key, Imf::StringAttribute(value));
  }

  const auto nc = static_cast<std::size_t>(data.channels);
  const std::size_t width = static_cast<std::size_t>(data.width);
  const auto frame_at = [&](const char* base, std::size_t element, std::ptrdiff_t first_row) {
    // OpenEXR addresses pixel (x, y) as base + x xstride + y ystride: a block starting at row first_row is
    // described by a base that many rows before it (the same arithmetic as the reader's data window).
    const std::size_t xstride = element * nc, ystride = xstride * width;
    Imf::FrameBuffer frame;
    for (std::size_t c = 0; c < nc; ++c)
      frame.insert(data.channel_names[c],
                   Imf::Slice(pixel, const_cast<char*>(base + c * element - first_row * std::ptrdiff_t(ystride)),
                              xstride, ystride));
    return frame;
  };
  use_exr_threads();
  try {
    Imf::OutputFile out(file.c_str(), header, Imf::globalThreadCount());
    if (pixel == Imf::FLOAT) {
      out.setFrameBuffer(frame_at(reinterpret_cast<const char*>(data.pixels.data()), sizeof(float), 0));
      out.writePixels(data.height);
    } else {
      // Half data is converted a block of rows at a time (in parallel, clamped to half's largest finite value:
      // beyond it half() gives Inf) into one reused buffer: a copy of the whole image in halves would be one more
      // large buffer whose first touch costs more than the conversion (BENCHMARKS.md, section 0).
      const std::size_t row = width * nc;
      const int rows = static_cast<int>(
          std::clamp<std::size_t>(kHalfBlockBytes / (row * sizeof(half)), 1, std::size_t(data.height)));
      std::vector<half> halves(std::size_t(rows) * row);
      for (int y0 = 0; y0 < data.height; y0 += rows) {
        const int n = std::min(rows, data.height - y0);
        const float* from = data.pixels.data() + std::size_t(y0) * row;
        tbb::parallel_for(Range(0, std::size_t(n) * row, kGrain), [&](const Range& r) {
          for (std::size_t i = r.begin(); i != r.end(); ++i) halves[i] = half(std::clamp(from[i], -65504.0f, 65504.0f));
        });
        out.setFrameBuffer(frame_at(reinterpret_cast<const char*>(halves.data()), sizeof(half), y0));
        out.writePixels(n);
      }
    }
  } catch (const std::exception& e) {
    fail(path, "cannot write: " + condense(e.what(), file, path));
  }
}

void write_with_backend(const std::string& path, const std::string& file, const detail::WriteSpec& spec,
                        const Image& data) {
  const std::string error = detail::backend_for_writing(path).write(file, spec, data.pixels.data());
  if (!error.empty()) fail(path, "cannot write: " + condense(error, file, path));
}

}  // namespace

namespace {

/// Reads the pixels of part 0 of an OpenEXR file with OpenEXR itself, straight into the interleaved float buffer in
/// OIIO's channel order. OIIO 2.4 reads through an intermediate buffer in the file's channel order and converts it
/// single-threaded: 2.0 s against 0.45 s for an uncompressed 8192x4096 RGB float file. Luminance/chroma files are read
/// as R, G, B through OpenEXR's RGBA interface. Returns false (nothing read) for files this path does not handle:
/// deep data, other subsampled channels, channels OIIO names differently.
bool read_exr_pixels(const std::string& path, const detail::FileSpec& spec, Image& image) {
  if (spec.deep) return false;
  use_exr_threads();
  try {
    if (spec.luminance_chroma) {
      detail::read_exr_luminance_chroma(path, spec, image.pixels.data());
      return true;
    }
    Imf::MultiPartInputFile file(path.c_str());
    Imf::InputPart part(file, 0);
    const Imath::Box2i dw = part.header().dataWindow();
    if (dw.min.x != spec.x || dw.min.y != spec.y || dw.max.x - dw.min.x + 1 != spec.width ||
        dw.max.y - dw.min.y + 1 != spec.height)
      return false;
    const Imf::ChannelList& list = part.header().channels();
    const std::size_t nc = static_cast<std::size_t>(image.channels);
    const std::size_t xstride = sizeof(float) * nc, ystride = xstride * static_cast<std::size_t>(image.width);
    char* origin = reinterpret_cast<char*>(image.pixels.data()) -
                   (static_cast<std::ptrdiff_t>(dw.min.y) * static_cast<std::ptrdiff_t>(ystride) +
                    static_cast<std::ptrdiff_t>(dw.min.x) * static_cast<std::ptrdiff_t>(xstride));
    Imf::FrameBuffer frame;
    for (std::size_t c = 0; c < nc; ++c) {
      const Imf::Channel* channel = list.findChannel(image.channel_names[c]);
      if (!channel || channel->xSampling != 1 || channel->ySampling != 1) return false;
      frame.insert(image.channel_names[c], Imf::Slice(Imf::FLOAT, origin + c * sizeof(float), xstride, ystride));
    }
    part.setFrameBuffer(frame);
    part.readPixels(dw.min.y, dw.max.y);
  } catch (const std::exception& e) {
    fail(path, "cannot read pixels (truncated or corrupt file?): " + condense(e.what()));
  }
  return true;
}

/// All channels of subimage 0, MIP level 0 as float, alpha moved last. OpenEXR files are read by OpenEXR
/// (`in` is null for them), other formats by the OIIO module.
Image read_pixels(const std::string& path, detail::BackendInput* in, const detail::FileSpec& spec) {
  Image image;
  image.width = spec.width;
  image.height = spec.height;
  image.channels = spec.nchannels;
  image.channel_names = spec.channel_names;
  image.alpha_channel = find_alpha(spec);
  image.pixels.resize(image.texel_count() * static_cast<std::size_t>(image.channels));
  if (!in) {
    if (!read_exr_pixels(path, spec, image)) fail(path, "cannot read pixels: unsupported OpenEXR channel layout");
  } else if (const std::string error = in->read(image.pixels.data()); !error.empty()) {
    fail(path, "cannot read pixels (truncated or corrupt file?): " + condense(error));
  }
  move_alpha_last(image);
  return image;
}

/// Counts NaN/Inf in the file's values and applies the policy. Done before colour conversion, which
/// would spread a non-finite value to the other channels of its texel. Returns the file's values below zero, counted
/// in the same pass: the returned pixels' count too as long as no later step changes them.
std::size_t handle_nonfinite(const std::string& path, Image& image, NonFinitePolicy policy, ReadReport& report) {
  const ValueCounts counts = count_values(image.pixels);
  const NonFiniteCounts& bad = counts.nonfinite;
  report.nan_count = bad.nan;
  report.posinf_count = bad.posinf;
  report.neginf_count = bad.neginf;
  const std::size_t n = report.nonfinite_count();
  if (n == 0) return counts.negative;
  if (policy == NonFinitePolicy::Error)
    fail(path, std::to_string(n) + " non-finite values (" + std::to_string(bad.nan) + " NaN, " +
                   std::to_string(bad.posinf + bad.neginf) + " Inf); pass --fix-nonfinite zero|clamp");
  apply_nonfinite_policy(image, policy);
  report.replaced_count = n;
  return counts.negative;
}

/// Decodes the pixels to the working space. Returns whether their values may have changed (a gamma curve, even of
/// 1, or a colour conversion): the values below zero counted before it no longer hold then.
bool decode_to_working_space(Image& image, const Decoding& decoding, ReadReport& report) {
  report.colorspace_reason = decoding.reason;
  report.working_space = working_space();
  if (decoding.gamma > 0.0) {
    char gamma[32];
    std::snprintf(gamma, sizeof gamma, "%g", decoding.gamma);
    report.file_colorspace = std::string("gamma ") + gamma;
    decode_gamma(image, decoding.gamma);
    report.converted = decoding.gamma != 1.0;
    return true;
  }
  report.file_colorspace = decoding.colorspace;
  if (decoding.colorspace != report.working_space && !is_data_colorspace(decoding.colorspace)) {
    convert_colorspace(image, decoding.colorspace, report.working_space);
    report.converted = true;
  }
  return report.converted;
}

}  // namespace

NonFinitePolicy parse_nonfinite_policy(const std::string& name) {
  const std::string n = lower(name);
  if (n == "error") return NonFinitePolicy::Error;
  if (n == "zero") return NonFinitePolicy::Zero;
  if (n == "clamp") return NonFinitePolicy::Clamp;
  throw Error("unknown non-finite policy '" + name + "' (use error, zero or clamp)");
}

const char* nonfinite_policy_name(NonFinitePolicy policy) {
  switch (policy) {
    case NonFinitePolicy::Error:
      return "error";
    case NonFinitePolicy::Zero:
      return "zero";
    case NonFinitePolicy::Clamp:
      return "clamp";
  }
  return "?";
}

std::string ReadReport::summary() const {
  std::string s = format + " " + pixel_type + ", colour space " + file_colorspace + " (" + colorspace_reason + ")";
  if (converted) s += " -> " + working_space;
  s += ", " + std::to_string(nonfinite_count()) + " non-finite (" + std::to_string(nan_count) + " NaN, " +
       std::to_string(posinf_count) + " +Inf, " + std::to_string(neginf_count) + " -Inf)";
  if (replaced_count > 0) s += std::string(" replaced by policy ") + nonfinite_policy_name(policy);
  s += ", " + std::to_string(negative_count) + " negative";
  for (const auto& note : notes) s += "; " + note;
  return s;
}

bool is_exr_compression(const std::string& name) { return exr_compressions().count(exr_compression_base(name)) > 0; }

const char* exr_compression_list() { return "none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab"; }

namespace {

/// Radiance and PFM files, decoded by envkit's codecs (image_codecs.h). Both hold linear float light with no
/// colour-space tag: the pixels are the working space unless ReadOptions::colorspace says otherwise; XYZE data
/// goes through the XYZ -> Rec.709 matrix first.
Image read_native_image(const std::string& path, detail::NativeFormat format, const ReadOptions& options,
                        ReadReport& report) {
  detail::NativeRead r =
      detail::read_native(path, format, [&](int w, int h, int c) { check_dimensions(path, w, h, c, options); });
  Image& image = r.image;
  report.format = r.format;
  report.pixel_type = r.pixel_type;
  report.notes = r.notes;
  const std::size_t file_negative = handle_nonfinite(path, image, options.nonfinite, report);
  bool changed = report.replaced_count > 0;
  try {
    if (r.xyze) {
      const std::array<double, 9> m = radiance_xyz_to_rec709();
      tbb::parallel_for(Range(0, image.texel_count(), kGrain / 4), [&](const Range& rr) {
        for (std::size_t t = rr.begin(); t != rr.end(); ++t) {
          float* px = &image.pixels[t * 3];
          const double x = px[0], y = px[1], z = px[2];
          for (int c = 0; c < 3; ++c) {
            const double v = m[static_cast<std::size_t>(3 * c)] * x + m[static_cast<std::size_t>(3 * c + 1)] * y +
                             m[static_cast<std::size_t>(3 * c + 2)] * z;
            px[c] = static_cast<float>(std::clamp(v, -double(FLT_MAX), double(FLT_MAX)));
          }
        }
      });
      image.channel_names = {"R", "G", "B"};
      if (!options.colorspace.empty()) report.notes.push_back("XYZE data: the colour-space option is ignored");
      decode_to_working_space(image, {canonical_colorspace("lin_rec709"), 0.0, "Radiance XYZE -> Rec.709"}, report);
      report.file_colorspace = "radiance xyz";
      changed = true;  // the matrix above
    } else if (!options.colorspace.empty()) {
      changed |= decode_to_working_space(image, {canonical_colorspace(options.colorspace), 0.0, "option"}, report);
    } else {
      changed |= decode_to_working_space(image, {working_space(), 0.0, "default for float data"}, report);
    }
  } catch (const Error& e) {
    fail(path, e.what());
  }
  report.negative_count = changed ? count_negative(image.pixels) : file_negative;
  return std::move(image);
}

}  // namespace

Image read_image(const std::string& path, const ReadOptions& options, ReadReport* report_out) {
  ReadReport report;
  report.policy = options.nonfinite;
  if (const detail::NativeFormat native = detail::sniff_native_format(path); native != detail::NativeFormat::None) {
    Image image = read_native_image(path, native, options, report);
    if (report_out) *report_out = std::move(report);
    return image;
  }
  // OpenEXR files are read by OpenEXR alone; a layout that path does not handle goes to the OIIO module.
  std::unique_ptr<detail::BackendInput> in;
  std::optional<detail::FileSpec> exr = detail::read_exr_spec(path);
  if (exr && exr->subsampled)  // OIIO refuses these too: no point loading it
    fail(path, "cannot read: subsampled OpenEXR channels are read only as luminance/chroma (Y, RY, BY and A)");
  if (exr && !detail::exr_layout_supported(*exr)) exr.reset();
  if (!exr) in = open_input(path);
  const detail::FileSpec spec = exr ? *exr : in->spec();
  check_header(path, spec, options);
  report.format = spec.format;
  report.pixel_type = spec.pixel_type;
  Image image = read_pixels(path, in.get(), spec);
  in.reset();
  image.metadata.insert(spec.metadata.begin(), spec.metadata.end());
  if (report.format == "openexr")
    if (std::string envmap = exr_envmap(path); !envmap.empty()) image.metadata["envmap"] = envmap;
  if (spec.x != spec.full_x || spec.y != spec.full_y || spec.width != spec.full_width ||
      spec.height != spec.full_height)
    report.notes.push_back("data window differs from the display window: the data window was read");

  const std::size_t file_negative = handle_nonfinite(path, image, options.nonfinite, report);
  bool changed = report.replaced_count > 0;
  try {
    changed |= decode_to_working_space(image, decide_decoding(spec, report.format, options, report), report);
  } catch (const Error& e) {
    fail(path, e.what());
  }
  if (spec.unassociated_alpha) {
    multiply_alpha(image, false);
    changed = true;
  }
  // One pass counted the file's non-finite values and its negatives: counted again only if a step changed values.
  report.negative_count = changed ? count_negative(image.pixels) : file_negative;
  if (report_out) *report_out = std::move(report);
  return image;
}

namespace {

/// The values of `data` a file of `format` with pixel type `type` cannot hold: beyond half's range for Half, negative
/// colour for Radiance (RGBE has no sign; its range exceeds float's).
ClampReport clamped_values(const Image& data, const std::string& format, PixelType type) {
  static constexpr FormatRange kRgbe{"rgbe", {FLT_MAX, FLT_MAX, FLT_MAX}, false};
  const std::span<const float> values(data.pixels.data(), data.pixels.size());
  if (format == "hdr") return count_clamped(values, data.channels, std::min(3, data.color_channels()), kRgbe);
  if (type == PixelType::Half) return count_clamped(values, data.channels, data.channels, kHalfRange);
  return {};
}

/// Header lines of a Radiance file: the carried metadata, then WriteOptions::metadata, and SOFTWARE.
std::map<std::string, std::string> radiance_variables(const Image& image, const WriteOptions& options) {
  std::map<std::string, std::string> variables;
  for (const auto& [key, value] : image.metadata)
    if (carried_metadata_key(key)) variables[key] = value;
  for (const auto& [key, value] : options.metadata) variables[key] = value;
  if (!variables.count("SOFTWARE")) variables["SOFTWARE"] = "envkit";
  return variables;
}

}  // namespace

ClampReport write_image(const std::string& path, const Image& image, const WriteOptions& options) {
  if (path.empty()) fail("", "empty output path");
  check_writable_image(path, image);
  const Target target = describe_target(path);
  check_envmap_option(path, image, target, options.envmap_attribute);
  const PixelType type = choose_pixel_type(path, target, options.pixel_type);

  // OpenEXR float or half output of an image whose channels go out as they are: written straight from the
  // caller's pixels (write_exr converts to half with the clamp), without the 400 MB copy of an 8k map.
  if (target.format == "openexr" && (type == PixelType::Float || type == PixelType::Half) &&
      writes_channels_as_they_are(image, target)) {
    AtomicOutput output(path);
    write_exr(path, output.temp_path(), image, type, image, options);
    output.commit();
    return clamped_values(image, target.format, type);
  }
  // Radiance output of an RGB image: encoded straight from the caller's pixels (the encoder reads the first three
  // channels and writes negatives as 0), without a copy.
  if (target.format == "hdr" && image.channels == 3 && image.alpha_channel < 0) {
    AtomicOutput output(path);
    detail::write_radiance_file(path, output.temp_path(), image, radiance_variables(image, options));
    output.commit();
    return clamped_values(image, target.format, type);
  }
  Image data = select_channels(image, target);
  const ClampReport clamped = clamped_values(data, target.format, type);
  try {
    if (type == PixelType::UInt8 || type == PixelType::UInt16) {
      // Integer files hold display-encoded values (never linear light in 8 or 16 bits) with unassociated
      // alpha (PNG's convention; TIFF is told so): un-premultiply in linear light, then encode.
      multiply_alpha(data, true);
      convert_colorspace(data, working_space(), encode_colorspace_for(target, options));
      clamp_all(data, 0.0f, 1.0f);
    } else if (type == PixelType::Half) {
      clamp_all(data, -65504.0f, 65504.0f);  // half's largest finite value; beyond it half() gives Inf
    }
  } catch (const Error& e) {
    fail(path, e.what());
  }

  AtomicOutput output(path);
  if (target.format == "pfm") {
    detail::write_pfm_file(path, output.temp_path(), data);
  } else if (target.format == "hdr") {
    detail::write_radiance_file(path, output.temp_path(), data, radiance_variables(image, options));
  } else if (target.format == "openexr") {
    write_exr(path, output.temp_path(), data, type, image, options);
  } else {
    detail::WriteSpec spec;
    try {
      spec = make_spec(data, target, type, image, options);
    } catch (const Error& e) {
      fail(path, e.what());
    }
    write_with_backend(path, output.temp_path(), spec, data);
  }
  output.commit();
  return clamped;
}

}  // namespace envkit
