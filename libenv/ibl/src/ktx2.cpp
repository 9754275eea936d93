#include <Imath/half.h>
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/core/input_checks.h>
#include <envkit/ibl/ktx2.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numeric>

namespace envkit {

std::string gpu_format_name(GpuFormat format) {
  switch (format) {
    case GpuFormat::Rgba16f:
      return "rgba16f";
    case GpuFormat::Rgba32f:
      return "rgba32f";
    case GpuFormat::B10G11R11:
      return "rg11b10f";
    case GpuFormat::E5B9G9R9:
      return "rgb9e5";
  }
  return "rgba16f";
}

GpuFormat parse_gpu_format(const std::string& name) {
  if (name == "rgba16f" || name == "half") return GpuFormat::Rgba16f;
  if (name == "rgba32f" || name == "float") return GpuFormat::Rgba32f;
  if (name == "rg11b10f" || name == "b10g11r11" || name == "r11g11b10") return GpuFormat::B10G11R11;
  if (name == "rgb9e5" || name == "e5b9g9r9" || name == "r9g9b9e5") return GpuFormat::E5B9G9R9;
  throw Error("unknown texel format '" + name + "' (expected rgba16f, rgba32f, rg11b10f or rgb9e5)");
}

int gpu_format_bytes(GpuFormat format) {
  switch (format) {
    case GpuFormat::Rgba16f:
      return 8;
    case GpuFormat::Rgba32f:
      return 16;
    default:
      return 4;
  }
}

std::uint32_t vk_format(GpuFormat format) {
  switch (format) {
    case GpuFormat::Rgba16f:
      return 97;
    case GpuFormat::Rgba32f:
      return 109;
    case GpuFormat::B10G11R11:
      return 122;
    case GpuFormat::E5B9G9R9:
      return 123;
  }
  return 0;
}

std::uint32_t dxgi_format(GpuFormat format) {
  switch (format) {
    case GpuFormat::Rgba16f:
      return 10;
    case GpuFormat::Rgba32f:
      return 2;
    case GpuFormat::B10G11R11:
      return 26;
    case GpuFormat::E5B9G9R9:
      return 67;
  }
  return 0;
}

namespace {

// Unsigned float with a 5-bit exponent (bias 15) and `mbits` mantissa bits (Vulkan's 11- and 10-bit floats),
// round to nearest; a mantissa carry moves into the exponent through the addition.
std::uint32_t encode_ufloat(double v, int mbits) {
  if (!(v > 0.0)) return 0;
  const std::uint32_t max_code = (30u << mbits) | ((1u << mbits) - 1u);
  int e = 0;
  const double f = std::frexp(v, &e);  // v = f 2^e, f in [0.5, 1)
  const int biased = e - 1 + 15;
  std::uint32_t code;
  if (biased <= 0) {
    code = std::uint32_t(std::lround(std::ldexp(v, 14 + mbits)));  // denormal: m / 2^mbits x 2^-14
  } else {
    const auto m = std::uint32_t(std::lround((2.0 * f - 1.0) * double(1u << mbits)));
    code = (std::uint32_t(biased) << mbits) + m;
  }
  return std::min(code, max_code);
}

double decode_ufloat(std::uint32_t code, int mbits) {
  const std::uint32_t e = code >> mbits, m = code & ((1u << mbits) - 1u);
  if (e == 0) return std::ldexp(double(m), -14 - mbits);
  return std::ldexp(1.0 + double(m) / double(1u << mbits), int(e) - 15);
}

float finite_or_zero(float v) { return std::isfinite(v) ? v : 0.0f; }

}  // namespace

std::uint32_t pack_b10g11r11(const float rgb[3]) {
  return encode_ufloat(finite_or_zero(rgb[0]), 6) | (encode_ufloat(finite_or_zero(rgb[1]), 6) << 11) |
         (encode_ufloat(finite_or_zero(rgb[2]), 5) << 22);
}

void unpack_b10g11r11(std::uint32_t bits, float rgb[3]) {
  rgb[0] = float(decode_ufloat(bits & 0x7ffu, 6));
  rgb[1] = float(decode_ufloat((bits >> 11) & 0x7ffu, 6));
  rgb[2] = float(decode_ufloat(bits >> 22, 5));
}

// EXT_texture_shared_exponent's encoding: N = 9 mantissa bits, bias B = 15, Emax = 31.
std::uint32_t pack_e5b9g9r9(const float rgb[3]) {
  constexpr int kN = 9, kB = 15;
  const double max_value = 511.0 / 512.0 * 65536.0;
  double c[3];
  for (int i = 0; i < 3; ++i) {
    const double v = finite_or_zero(rgb[i]);
    c[i] = std::clamp(v, 0.0, max_value);
  }
  const double maxc = std::max({c[0], c[1], c[2]});
  if (maxc <= 0.0) return 0;
  int exp_p = std::max(-kB - 1, int(std::floor(std::log2(maxc)))) + 1 + kB;
  const double max_s = std::floor(maxc / std::ldexp(1.0, exp_p - kB - kN) + 0.5);
  if (max_s >= double(1 << kN)) ++exp_p;
  std::uint32_t out = std::uint32_t(exp_p) << 27;
  for (int i = 0; i < 3; ++i) {
    const auto m = std::uint32_t(std::min(511.0, std::floor(c[i] / std::ldexp(1.0, exp_p - kB - kN) + 0.5)));
    out |= m << (9 * i);
  }
  return out;
}

void unpack_e5b9g9r9(std::uint32_t bits, float rgb[3]) {
  const int e = int(bits >> 27);
  for (int i = 0; i < 3; ++i) rgb[i] = float(std::ldexp(double((bits >> (9 * i)) & 0x1ffu), e - 15 - 9));
}

namespace {

void pack_texel(const Image& image, GpuFormat format, std::size_t t, std::uint8_t* dst) {
  const int colour = std::min(3, image.color_channels());
  const float* px = image.pixels.data() + t * image.channels;
  float v[4] = {0.0f, 0.0f, 0.0f, 1.0f};
  for (int c = 0; c < colour; ++c) v[c] = finite_or_zero(px[c]);
  if (colour == 1) v[1] = v[2] = v[0];  // grey maps fill RGB
  if (image.alpha_channel >= 0) v[3] = finite_or_zero(px[image.alpha_channel]);
  switch (format) {
    case GpuFormat::Rgba32f:
      std::memcpy(dst, v, 16);
      break;
    case GpuFormat::Rgba16f:
      for (int c = 0; c < 4; ++c) {
        // Beyond half's range: the largest finite half, never Inf.
        const Imath::half h(std::clamp(v[c], -65504.0f, 65504.0f));
        const std::uint16_t b = h.bits();
        std::memcpy(dst + 2 * c, &b, 2);
      }
      break;
    case GpuFormat::B10G11R11: {
      const std::uint32_t b = pack_b10g11r11(v);
      std::memcpy(dst, &b, 4);
      break;
    }
    case GpuFormat::E5B9G9R9: {
      const std::uint32_t b = pack_e5b9g9r9(v);
      std::memcpy(dst, &b, 4);
      break;
    }
  }
}

}  // namespace

ClampReport count_clamped(const Image& image, GpuFormat format) {
  static constexpr FormatRange kRg11b10f{"rg11b10f", {65024.0, 65024.0, 64512.0}, false};
  static constexpr FormatRange kRgb9e5{"rgb9e5", {65408.0, 65408.0, 65408.0}, false};
  static constexpr FormatRange kRgba16f{"rgba16f", {65504.0, 65504.0, 65504.0}, true};
  const FormatRange* range = format == GpuFormat::B10G11R11  ? &kRg11b10f
                             : format == GpuFormat::E5B9G9R9 ? &kRgb9e5
                             : format == GpuFormat::Rgba16f  ? &kRgba16f
                                                             : nullptr;
  if (!range) return {};
  return count_clamped({image.pixels.data(), image.pixels.size()}, image.channels, std::min(3, image.color_channels()),
                       *range);
}

std::vector<std::uint8_t> pack_texels(const Image& image, GpuFormat format) {
  const std::size_t bytes = std::size_t(gpu_format_bytes(format));
  std::vector<std::uint8_t> out(image.texel_count() * bytes);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, image.texel_count(), 16384),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t t = r.begin(); t < r.end(); ++t)
                        pack_texel(image, format, t, out.data() + t * bytes);
                    });
  return out;
}

namespace {

void put32(std::vector<std::uint8_t>& b, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(std::uint8_t(v >> (8 * i)));
}
void set64(std::vector<std::uint8_t>& b, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b[at + i] = std::uint8_t(v >> (8 * i));
}
void set32(std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + i] = std::uint8_t(v >> (8 * i));
}

struct Sample {
  std::uint32_t offset, bits, channel, qualifiers, lower, upper;
};

constexpr std::uint32_t kFloat = 0x80, kSigned = 0x40, kExponent = 0x20;
constexpr std::uint32_t kOne = 0x3F800000u, kMinusOne = 0xBF800000u;

std::vector<Sample> samples_of(GpuFormat format) {
  switch (format) {
    case GpuFormat::Rgba16f:
      return {{0, 16, 0, kFloat | kSigned, kMinusOne, kOne},
              {16, 16, 1, kFloat | kSigned, kMinusOne, kOne},
              {32, 16, 2, kFloat | kSigned, kMinusOne, kOne},
              {48, 16, 15, kFloat | kSigned, kMinusOne, kOne}};
    case GpuFormat::Rgba32f:
      return {{0, 32, 0, kFloat | kSigned, kMinusOne, kOne},
              {32, 32, 1, kFloat | kSigned, kMinusOne, kOne},
              {64, 32, 2, kFloat | kSigned, kMinusOne, kOne},
              {96, 32, 15, kFloat | kSigned, kMinusOne, kOne}};
    case GpuFormat::B10G11R11:
      return {{0, 11, 0, kFloat, 0, kOne}, {11, 11, 1, kFloat, 0, kOne}, {22, 10, 2, kFloat, 0, kOne}};
    case GpuFormat::E5B9G9R9:
      // Mantissa samples with 1.0 at 8448 and the shared exponent (bias 15, max 31) once per channel, as
      // KTX-Software's descriptor for this format has them.
      return {{0, 9, 0, 0, 0, 8448},         {27, 5, 0, kExponent, 15, 31}, {9, 9, 1, 0, 0, 8448},
              {27, 5, 1, kExponent, 15, 31}, {18, 9, 2, 0, 0, 8448},        {27, 5, 2, kExponent, 15, 31}};
  }
  return {};
}

std::vector<std::uint8_t> basic_dfd(GpuFormat format) {
  const std::vector<Sample> samples = samples_of(format);
  const std::uint32_t block = 24 + 16 * std::uint32_t(samples.size());
  std::vector<std::uint8_t> d;
  put32(d, 4 + block);                                 // dfdTotalSize
  put32(d, 0);                                         // vendorId 0 (Khronos), descriptorType 0 (basic)
  put32(d, 2u | (block << 16));                        // versionNumber 2 (1.3), descriptorBlockSize
  put32(d, 1u | (1u << 8) | (1u << 16) | (0u << 24));  // RGBSDA, BT.709 primaries, linear, alpha straight
  put32(d, 0);                                         // texel block 1x1x1x1
  put32(d, std::uint32_t(gpu_format_bytes(format)));   // bytesPlane0
  put32(d, 0);                                         // bytesPlane4..7
  for (const Sample& s : samples) {
    put32(d, s.offset | ((s.bits - 1) << 16) | ((s.channel | s.qualifiers) << 24));
    put32(d, 0);  // sample position
    put32(d, s.lower);
    put32(d, s.upper);
  }
  return d;
}

}  // namespace

ClampReport write_ktx2(const std::string& path, const std::vector<const Image*>& levels, const Ktx2Options& options) {
  if (levels.empty()) fail(path, "no levels to write");
  if (options.faces != 1 && options.faces != 6) fail(path, "a KTX2 texture has 1 or 6 faces");
  const int width = levels[0]->width, height = levels[0]->height / options.faces;
  if (options.faces == 6 && levels[0]->height != 6 * width) fail(path, "cube levels must be N x 6N vertical strips");
  for (std::size_t m = 0; m < levels.size(); ++m) {
    const int w = std::max(1, width >> m), h = std::max(1, height >> m);
    if (levels[m]->width != w || levels[m]->height != h * options.faces)
      fail(path, "level " + std::to_string(m) + " is " + std::to_string(levels[m]->width) + "x" +
                     std::to_string(levels[m]->height) + ", expected " + std::to_string(w) + "x" +
                     std::to_string(h * options.faces));
  }
  const std::uint32_t level_count = std::uint32_t(levels.size());
  const int bytes = gpu_format_bytes(options.format);
  const std::size_t align = std::lcm(std::size_t(bytes), std::size_t(4));

  std::vector<std::uint8_t> f = {0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A};
  put32(f, vk_format(options.format));
  put32(f, options.format == GpuFormat::Rgba16f ? 2 : 4);  // typeSize
  put32(f, std::uint32_t(width));
  put32(f, std::uint32_t(height));
  put32(f, 0);  // pixelDepth
  put32(f, 0);  // layerCount
  put32(f, std::uint32_t(options.faces));
  put32(f, level_count);
  put32(f, 0);  // supercompressionScheme: none
  const std::size_t index_at = f.size();
  f.resize(f.size() + 32, 0);  // dfd, kvd, sgd offsets and lengths
  const std::size_t level_index_at = f.size();
  f.resize(f.size() + 24 * std::size_t(level_count), 0);

  const std::vector<std::uint8_t> dfd = basic_dfd(options.format);
  set32(f, index_at, std::uint32_t(f.size()));
  set32(f, index_at + 4, std::uint32_t(dfd.size()));
  f.insert(f.end(), dfd.begin(), dfd.end());

  std::map<std::string, std::string> kv = options.key_values;
  kv["KTXwriter"] = "envkit";
  const std::size_t kvd_at = f.size();
  for (const auto& [key, value] : kv) {  // std::map: sorted by key bytes, as the specification requires
    put32(f, std::uint32_t(key.size() + 1 + value.size() + 1));
    f.insert(f.end(), key.begin(), key.end());
    f.push_back(0);
    f.insert(f.end(), value.begin(), value.end());
    f.push_back(0);
    while (f.size() % 4 != 0) f.push_back(0);
  }
  set32(f, index_at + 8, std::uint32_t(kvd_at));
  set32(f, index_at + 12, std::uint32_t(f.size() - kvd_at));
  // sgdByteOffset / sgdByteLength stay 0.

  // Level offsets first (smallest level first in the file), then the header and each level written in turn: no
  // copy of the levels into one buffer.
  std::vector<std::size_t> level_at(level_count);
  std::size_t end = f.size();
  for (int m = int(level_count) - 1; m >= 0; --m) {
    const std::size_t size = levels[m]->texel_count() * std::size_t(bytes);
    end = (end + align - 1) / align * align;
    level_at[m] = end;
    const std::size_t at = level_index_at + 24 * std::size_t(m);
    set64(f, at, end);
    set64(f, at + 8, size);
    set64(f, at + 16, size);
    end += size;
  }

  ClampReport clamped;
  for (const Image* level : levels) clamped.add(count_clamped(*level, options.format));
  AtomicOutput out(path);
  {
    AtomicOutputStream os(out);
    os.write(reinterpret_cast<const char*>(f.data()), std::streamsize(f.size()));
    std::size_t written = f.size();
    for (int m = int(level_count) - 1; m >= 0 && os; --m) {
      const std::vector<std::uint8_t> data = pack_texels(*levels[m], options.format);
      const char zeros[16] = {};
      os.write(zeros, std::streamsize(level_at[m] - written));
      os.write(reinterpret_cast<const char*>(data.data()), std::streamsize(data.size()));
      written = level_at[m] + data.size();
    }
    os.close();
  }
  out.commit();
  return clamped;
}

namespace {

const std::uint8_t kKtx2Id[12] = {0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A};

std::string read_all(const std::string& path) {
  require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "cannot read");
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::uint32_t le32(const std::string& b, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | std::uint8_t(b[at + i]);
  return v;
}

std::string format_for(std::uint32_t code, bool vulkan) {
  for (GpuFormat f : {GpuFormat::Rgba16f, GpuFormat::Rgba32f, GpuFormat::B10G11R11, GpuFormat::E5B9G9R9})
    if ((vulkan ? vk_format(f) : dxgi_format(f)) == code) return gpu_format_name(f);
  return std::string(vulkan ? "vk " : "dxgi ").append(std::to_string(code));
}

}  // namespace

bool is_gpu_texture(const std::string& path) {
  // A sniff must not open a FIFO or a device (open() blocks on a FIFO without a writer): those are no textures, and
  // the reader the caller falls back to refuses them by name.
  if (std::error_code ec; !std::filesystem::is_regular_file(path, ec)) return false;
  std::ifstream in(path, std::ios::binary);
  char head[12] = {};
  in.read(head, 12);
  if (in.gcount() >= 4 && std::memcmp(head, "DDS ", 4) == 0) return true;
  return in.gcount() == 12 && std::memcmp(head, kKtx2Id, 12) == 0;
}

GpuTextureInfo read_gpu_texture_info(const std::string& path) {
  const std::string b = read_all(path);
  GpuTextureInfo info;
  if (b.size() >= 148 && b.compare(0, 4, "DDS ") == 0) {
    info.container = "dds";
    info.height = int(le32(b, 12));
    info.width = int(le32(b, 16));
    info.levels = std::max(1, int(le32(b, 28)));
    if (b.compare(84, 4, "DX10") != 0) fail(path, "DDS without a DX10 header");
    info.format = format_for(le32(b, 128), false);
    info.faces = (le32(b, 136) & 0x4u) ? 6 : 1;
    return info;
  }
  if (b.size() < 80 || std::memcmp(b.data(), kKtx2Id, 12) != 0) fail(path, "not a KTX2 or DDS file");
  info.container = "ktx2";
  info.format = format_for(le32(b, 12), true);
  info.width = int(le32(b, 20));
  info.height = int(le32(b, 24));
  info.faces = int(le32(b, 36));
  info.levels = std::max(1, int(le32(b, 40)));
  const std::size_t kvd = le32(b, 56), kvd_len = le32(b, 60);
  if (kvd + kvd_len > b.size()) fail(path, "key/value data beyond the end of the file");
  for (std::size_t at = kvd; at + 4 <= kvd + kvd_len;) {
    const std::size_t len = le32(b, at);
    if (at + 4 + len > kvd + kvd_len) fail(path, "malformed key/value data");
    const std::string kv = b.substr(at + 4, len);
    const std::size_t nul = kv.find('\0');
    if (nul != std::string::npos) {
      std::string value = kv.substr(nul + 1);
      if (!value.empty() && value.back() == '\0') value.pop_back();
      info.key_values[kv.substr(0, nul)] = value;
    }
    at += 4 + ((len + 3) / 4) * 4;
  }
  return info;
}

}  // namespace envkit
