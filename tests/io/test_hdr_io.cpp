// envkit's own Radiance .hdr and PFM codecs (image_codecs.h) as read_image/write_image use them, and the input checks
// every reader makes (input_checks.h).
#include <OpenImageIO/imageio.h>
#include <envkit/core/error.h>
#include <envkit/core/image.h>
#include <envkit/core/input_checks.h>
#include <envkit/io/image_codecs.h>
#include <envkit/io/image_io.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "cli_support.h"

namespace {
namespace fs = std::filesystem;
using envkit::Error;
using envkit::Image;

class HdrIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("envkit_hdr_io_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  void write_bytes(const std::string& file, const std::string& bytes) const {
    std::ofstream(file, std::ios::binary) << bytes;
  }
  static std::string read_bytes(const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  static std::string error_of(const std::function<void()>& f) {
    try {
      f();
    } catch (const Error& e) {
      return e.what();
    }
    return "(no error)";
  }
  fs::path dir_;
};

/// An RGBE pixel whose every component decodes exactly: mantissa m, exponent byte 136 - k gives m 2^-k.
std::string rgbe(unsigned char r, unsigned char g, unsigned char b, unsigned char e) {
  return std::string{static_cast<char>(r), static_cast<char>(g), static_cast<char>(b), static_cast<char>(e)};
}

/// Asymmetric test picture with values that RGBE stores exactly (mantissa 2^-7 steps, exponent byte 129).
float exact_value(int x, int y, int c) { return static_cast<float>(((x * 7 + y * 31 + c * 13) % 127) + 128) / 128.0f; }

Image exact_picture(int w, int h) {
  Image img(w, h, 3);
  img.channel_names = {"R", "G", "B"};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) img.at(x, y, c) = exact_value(x, y, c);
  return img;
}

std::string exact_pixel(int x, int y) {
  auto m = [&](int c) { return static_cast<unsigned char>(exact_value(x, y, c) * 128.0f); };
  return rgbe(m(0), m(1), m(2), 129);
}

/// A scanline in new-style RLE written as literal dumps only (an encoder independent of envkit's).
std::string rle_dumps(const std::vector<std::string>& pixels) {
  const int n = static_cast<int>(pixels.size());
  std::string out = {2, 2, static_cast<char>(n >> 8), static_cast<char>(n & 0xff)};
  for (int c = 0; c < 4; ++c)
    for (int i = 0; i < n; i += 128) {
      const int count = std::min(128, n - i);
      out += static_cast<char>(count);
      for (int k = 0; k < count; ++k) out += pixels[static_cast<std::size_t>(i + k)][static_cast<std::size_t>(c)];
    }
  return out;
}

const std::string kHeader = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n";

// ---- orientation ----------------------------------------------------------------------------------------------------

TEST_F(HdrIoTest, AllEightResolutionStringsGiveTheDisplayedPicture) {
  // The picture as displayed, 3 wide and 2 high:  A B C
  //                                              D E F
  // and the order in which each resolution string stores its texels (Radiance: +Y is up, +X to the right; the first
  // axis is the scanline axis, the sign says where the first scanline and the first pixel are).
  const std::string names = "ABCDEF";
  struct Case {
    const char* resolution;
    const char* order;
  };
  const Case cases[] = {
      {"-Y 2 +X 3", "ABCDEF"}, {"+Y 2 +X 3", "DEFABC"}, {"-Y 2 -X 3", "CBAFED"}, {"+Y 2 -X 3", "FEDCBA"},
      {"+X 3 -Y 2", "ADBECF"}, {"+X 3 +Y 2", "DAEBFC"}, {"-X 3 -Y 2", "CFBEAD"}, {"-X 3 +Y 2", "FCEBDA"},
  };
  for (const Case& c : cases) {
    std::string file = std::string("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n") + c.resolution + "\n";
    for (const char* p = c.order; *p; ++p) {
      const auto k = static_cast<unsigned char>(*p - 'A');
      file += rgbe(static_cast<unsigned char>(128 + 10 * k), 130, 140,
                   129);  // red = 1 + 10k/128
    }
    write_bytes(path("o.hdr"), file);
    const Image img = envkit::read_image(path("o.hdr"));
    ASSERT_EQ(img.width, 3) << c.resolution;
    ASSERT_EQ(img.height, 2) << c.resolution;
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 3; ++x) {
        const int k = static_cast<int>(names.find(names[static_cast<std::size_t>(y * 3 + x)]));
        EXPECT_EQ(img.at(x, y, 0), (128.0f + 10.0f * static_cast<float>(k)) / 128.0f)
            << c.resolution << " texel (" << x << ", " << y << ") should be " << names[static_cast<std::size_t>(k)];
      }
  }
}

TEST_F(HdrIoTest, BottomUpAndMirroredRunLengthFilesMatchTheStandardOne) {
  const int w = 300, h = 7;  // > 128 pixels: two dumps per channel
  const Image expected = exact_picture(w, h);
  struct Case {
    const char* first;
    const char* second;
    bool bottom_up, mirrored;
  };
  for (const Case& c : {Case{"-Y", "+X", false, false}, Case{"+Y", "+X", true, false}, Case{"-Y", "-X", false, true},
                        Case{"+Y", "-X", true, true}}) {
    std::string file = kHeader + c.first + " " + std::to_string(h) + " " + c.second + " " + std::to_string(w) + "\n";
    for (int s = 0; s < h; ++s) {
      const int y = c.bottom_up ? h - 1 - s : s;
      std::vector<std::string> pixels;
      for (int p = 0; p < w; ++p) pixels.push_back(exact_pixel(c.mirrored ? w - 1 - p : p, y));
      file += rle_dumps(pixels);
    }
    write_bytes(path("rle.hdr"), file);
    const Image img = envkit::read_image(path("rle.hdr"));
    ASSERT_EQ(img.width, w);
    ASSERT_EQ(img.height, h);
    EXPECT_EQ(img.pixels, expected.pixels) << c.first << " " << c.second;
  }
}

TEST_F(HdrIoTest, StandardFilesReadLikeOpenImageIO) {
  // OIIO decodes the standard orientation right; envkit's decode must agree with it exactly.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Image img(61, 17, 3);
  img.channel_names = {"R", "G", "B"};
  for (float& v : img.pixels) v = std::exp(12.0f * u(rng) - 6.0f) * (u(rng) < 0.1f ? 0.0f : 1.0f);
  for (int x = 10; x < 40; ++x)
    for (int c = 0; c < 3; ++c) img.at(x, 3, c) = 2.5f;  // a run
  envkit::write_image(path("std.hdr"), img);
  const Image ours = envkit::read_image(path("std.hdr"));
  auto in = OIIO::ImageInput::open(path("std.hdr"));
  ASSERT_TRUE(in) << OIIO::geterror();
  ASSERT_EQ(in->spec().width, 61);
  ASSERT_EQ(in->spec().height, 17);
  std::vector<float> theirs(img.pixels.size());
  ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::FLOAT, theirs.data()));
  ASSERT_EQ(ours.pixels.size(), theirs.size());
  for (std::size_t i = 0; i < theirs.size(); ++i) ASSERT_EQ(ours.pixels[i], theirs[i]) << i;
}

// ---- scanline encodings ---------------------------------------------------------------------------------------------

TEST_F(HdrIoTest, OldStyleRepeatsAndFlatScanlinesDecode) {
  // Width 10. Scanline 0: old-style, pixel a and 4 repeats, pixel b and 4 repeats; scanline 1: new-style; scanline 2:
  // flat.
  const std::string a = rgbe(128, 0, 0, 129), b = rgbe(0, 128, 0, 130);
  std::string file = kHeader + "-Y 3 +X 10\n";
  file += a + rgbe(1, 1, 1, 4) + b + rgbe(1, 1, 1, 4);  // a x5, b x5
  file += rle_dumps(std::vector<std::string>(10, b));
  for (int i = 0; i < 10; ++i) file += i % 2 ? a : b;
  write_bytes(path("old.hdr"), file);
  const Image img = envkit::read_image(path("old.hdr"));
  for (int x = 0; x < 10; ++x) {
    EXPECT_EQ(img.at(x, 0, 0), x < 5 ? 1.0f : 0.0f) << x;
    EXPECT_EQ(img.at(x, 0, 1), x < 5 ? 0.0f : 2.0f) << x;
    EXPECT_EQ(img.at(x, 1, 1), 2.0f) << x;
    EXPECT_EQ(img.at(x, 2, 0), x % 2 ? 1.0f : 0.0f) << x;
  }
}

TEST_F(HdrIoTest, ConsecutiveRepeatCodesShiftTheCount) {
  // Radiance: a second consecutive repeat pixel counts in units of 256.
  const std::string a = rgbe(128, 128, 128, 129);
  std::string file = kHeader + "-Y 1 +X 258\n" + a + rgbe(1, 1, 1, 1) + rgbe(1, 1, 1, 1);  // 1 + 1 + 256
  write_bytes(path("shift.hdr"), file);
  const Image img = envkit::read_image(path("shift.hdr"));
  ASSERT_EQ(img.width, 258);
  for (int x = 0; x < 258; ++x) EXPECT_EQ(img.at(x, 0, 2), 1.0f) << x;
}

TEST_F(HdrIoTest, RoundTripIsWithinHalfAMantissaStepAndReencodesIdentically) {
  for (const auto& [w, h] : {std::pair{257, 33}, std::pair{5, 3}, std::pair{40000, 2}}) {
    std::mt19937 rng(static_cast<unsigned>(w));
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    Image img(w, h, 3);
    img.channel_names = {"R", "G", "B"};
    for (float& v : img.pixels) v = std::exp(30.0f * u(rng) - 15.0f);
    envkit::write_image(path("rt.hdr"), img);
    const Image back = envkit::read_image(path("rt.hdr"));
    ASSERT_EQ(back.width, w);
    for (std::size_t t = 0; t < img.texel_count(); ++t) {
      const float* a = &img.pixels[3 * t];
      const float m = std::max({a[0], a[1], a[2]});
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(back.pixels[3 * t + static_cast<std::size_t>(c)], a[c], m / 255.0f) << w << " texel " << t;
    }
    envkit::write_image(path("rt2.hdr"),
                        back);  // decoded values are representable: bytes must not change
    EXPECT_EQ(read_bytes(path("rt.hdr")), read_bytes(path("rt2.hdr"))) << w;
  }
}

TEST_F(HdrIoTest, DecodeDoesNotDependOnTheThreadCount) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.0f, 4.0f);
  Image img(512, 64, 3);
  img.channel_names = {"R", "G", "B"};
  for (float& v : img.pixels) v = u(rng);
  envkit::write_image(path("t.hdr"), img);
  const Image all = envkit::read_image(path("t.hdr"));
  Image one;
  tbb::task_arena(1).execute([&] { one = envkit::read_image(path("t.hdr")); });
  EXPECT_EQ(all.pixels, one.pixels);
}

// ---- encoder: the bytes written ---------------------------------------------------------------------------------

/// The RGBE of one texel as the encoder computed it before its fast paths (frexp and ldexp per texel): the reference
/// the fast encoder must reproduce byte for byte. Below 2^-120, where 2^(8 - e) is no float, in double.
void reference_rgbe(const float* rgb, unsigned char* out) {
  const float r = std::max(rgb[0], 0.0f), g = std::max(rgb[1], 0.0f), b = std::max(rgb[2], 0.0f);
  const float v = std::max({r, g, b});
  if (!(v >= 1e-38f)) {
    std::memset(out, 0, 4);
    return;
  }
  int e = 0;
  (void)std::frexp(v, &e);
  auto mantissas = [&](int exponent, long* m) {
    if (8 - exponent <= 127) {
      const float k = std::ldexp(1.0f, 8 - exponent);
      m[0] = static_cast<long>(r * k + 0.5f), m[1] = static_cast<long>(g * k + 0.5f),
      m[2] = static_cast<long>(b * k + 0.5f);
    } else {
      const double k = std::ldexp(1.0, 8 - exponent);
      m[0] = static_cast<long>(r * k + 0.5), m[1] = static_cast<long>(g * k + 0.5),
      m[2] = static_cast<long>(b * k + 0.5);
    }
  };
  long m[3];
  mantissas(e, m);
  if (std::max({m[0], m[1], m[2]}) > 255) mantissas(++e, m);
  if (e + 128 > 255) {
    std::memset(out, 255, 4);
    return;
  }
  for (int c = 0; c < 3; ++c) out[c] = static_cast<unsigned char>(std::min(m[c], 255L));
  out[3] = static_cast<unsigned char>(e + 128);
}

/// The previous encoder's new-style RLE of one plane (runs of >= 4 equal bytes, 127 at most, and dumps of at most 128),
/// byte by byte.
void reference_plane(const unsigned char* plane, int n, std::string& out) {
  int i = 0;
  while (i < n) {
    int run_start = i, run_len = 0;
    while (run_start < n) {
      run_len = 1;
      while (run_start + run_len < n && run_len < 127 && plane[run_start + run_len] == plane[run_start]) ++run_len;
      if (run_len >= 4) break;
      run_start += run_len;
    }
    if (run_start >= n) run_len = 0, run_start = n;
    while (i < run_start) {
      const int count = std::min(128, run_start - i);
      out += static_cast<char>(count);
      out.append(reinterpret_cast<const char*>(plane + i), static_cast<std::size_t>(count));
      i += count;
    }
    if (run_len >= 4) {
      out += static_cast<char>(128 + run_len);
      out += static_cast<char>(plane[run_start]);
      i = run_start + run_len;
    }
  }
}

/// The pixel data (after the header) the reference encoder writes for `img`.
std::string reference_pixels(const Image& img) {
  std::string out;
  const int w = img.width;
  std::vector<unsigned char> rgbe(static_cast<std::size_t>(w) * 4), plane(static_cast<std::size_t>(w));
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < w; ++x) reference_rgbe(img.at(x, y), &rgbe[static_cast<std::size_t>(x) * 4]);
    if (w < 8 || w > 32767) {
      out.append(reinterpret_cast<const char*>(rgbe.data()), rgbe.size());
      continue;
    }
    out += {2, 2, static_cast<char>(w >> 8), static_cast<char>(w & 0xff)};
    for (int c = 0; c < 4; ++c) {
      for (int x = 0; x < w; ++x) plane[static_cast<std::size_t>(x)] = rgbe[static_cast<std::size_t>(x) * 4 + c];
      reference_plane(plane.data(), w, out);
    }
  }
  return out;
}

/// The pixel data of an encoded file: what follows the resolution line.
std::string encoded_pixels(const Image& img) {
  const std::vector<unsigned char> bytes = envkit::encode_radiance(img);
  const std::string all(bytes.begin(), bytes.end());
  const std::string res = "\n-Y " + std::to_string(img.height) + " +X " + std::to_string(img.width) + "\n";
  const std::size_t at = all.find(res);
  return at == std::string::npos ? std::string() : all.substr(at + res.size());
}

/// Finite values that exercise every path of the encoder: rounding carries into the next exponent, both ends of the
/// fast exponent range (2^-120, 2^126) and beyond, 1e-38 and denormals, negatives, -0.
std::vector<float> special_values() {
  std::vector<float> v = {0.0f,
                          -0.0f,
                          -1.0f,
                          -1e30f,
                          1e-38f,
                          9.99e-39f,
                          1.2e-38f,
                          1e-45f,
                          1.0f,
                          0.5f,
                          2.0f,
                          0.998f,
                          0.999f,
                          0.9999999f,
                          255.5f / 256.0f,
                          255.49f / 256.0f,
                          127.5f / 128.0f,
                          std::numeric_limits<float>::max(),
                          std::numeric_limits<float>::min()};
  for (int e = -130; e <= 128; ++e) {
    const float p = std::ldexp(1.0f, e);
    if (std::isfinite(p)) v.push_back(p);
    for (float f : {0.999f, 0.99999994f, 1.5f, 1.99609375f, 1.998046875f, 1.9999999f}) {
      const float q = std::ldexp(f, e);
      if (std::isfinite(q)) v.push_back(q);
    }
  }
  return v;
}

/// An image of `w` x `h` whose rows cycle through the cases: log-uniform noise over a wide range, black, runs of many
/// lengths (around the limits 4, 127 and 128), special values mixed with ordinary ones, and representable values.
Image encoder_cases(int w, int h, int channels = 3) {
  Image img(w, h, channels);
  img.channel_names = envkit::default_channel_names(channels);
  std::mt19937 rng(static_cast<unsigned>(w * 131 + h));
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  const std::vector<float> special = special_values();
  const int lengths[] = {1, 2, 3, 4, 5, 126, 127, 128, 129, 131, 254, 255, 256, 300};
  for (int y = 0; y < h; ++y) {
    float* row = img.at(0, y);
    const std::size_t n = static_cast<std::size_t>(w) * static_cast<std::size_t>(channels);
    switch (y % 5) {
      case 0:
        for (std::size_t i = 0; i < n; ++i) row[i] = std::exp(60.0f * u(rng) - 30.0f);
        break;
      case 1:
        std::fill(row, row + n, 0.0f);
        break;
      case 2: {  // runs: whole texels repeated
        int x = 0, k = 0;
        while (x < w) {
          const int len = lengths[k++ % 14];
          const float value = std::exp(8.0f * u(rng) - 4.0f) * (k % 3 == 0 ? 0.0f : 1.0f);
          for (int i = 0; i < len && x < w; ++i, ++x)
            for (int c = 0; c < channels; ++c) img.at(x, y, c) = value * (1.0f + 0.25f * static_cast<float>(c));
        }
        break;
      }
      case 3:
        for (std::size_t i = 0; i < n; ++i)
          row[i] = u(rng) < 0.5f ? special[static_cast<std::size_t>(u(rng) * static_cast<float>(special.size() - 1))]
                                 : u(rng) * 10.0f;
        break;
      default:  // representable values with long runs in the exponent plane
        for (std::size_t i = 0; i < n; ++i) row[i] = std::floor(u(rng) * 4.0f) / 2.0f + 1.0f;
    }
  }
  return img;
}

TEST_F(HdrIoTest, EncoderWritesTheReferenceEncodersBytes) {
  // Widths below 8 and above 32767 give flat scanlines, the others run-length ones; odd widths leave a tail for the
  // 4-texel fast path and the 16-byte run search.
  for (const int w : {1, 3, 5, 7, 8, 9, 15, 16, 17, 19, 31, 127, 128, 129, 257, 1001, 4099, 32767, 32768, 33001}) {
    const Image img = encoder_cases(w, w > 5000 ? 5 : 15);
    const std::string expected = reference_pixels(img);
    ASSERT_EQ(encoded_pixels(img), expected) << "width " << w;
  }
  // Every special value as the largest component of a texel, with smaller and equal neighbours.
  const std::vector<float> special = special_values();
  Image img(static_cast<int>(special.size()), 3, 3);
  img.channel_names = {"R", "G", "B"};
  for (int x = 0; x < img.width; ++x) {
    const float v = special[static_cast<std::size_t>(x)];
    img.at(x, 0, 0) = v, img.at(x, 0, 1) = v * 0.5f, img.at(x, 0, 2) = v * 0.0039f;
    img.at(x, 1, 0) = v * 0.25f, img.at(x, 1, 1) = v, img.at(x, 1, 2) = v;
    img.at(x, 2, 0) = 0.0f, img.at(x, 2, 1) = -v, img.at(x, 2, 2) = v;
  }
  EXPECT_EQ(encoded_pixels(img), reference_pixels(img));
  // Four channels (stride 4: the encoder reads the first three).
  const Image rgba = encoder_cases(300, 10, 4);
  EXPECT_EQ(encoded_pixels(rgba), reference_pixels(rgba));
}

TEST_F(HdrIoTest, EncoderTexelPolicyForTinyHugeAndNonFiniteValues) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const std::vector<std::array<float, 3>> texels = {
      {0.0f, 0.0f, 0.0f},                    // black
      {-2.0f, 1.0f, 0.0f},                   // negative -> 0
      {9e-39f, 0.0f, 0.0f},                  // below 1e-38 -> black
      {std::ldexp(1.0f, -125), 0.0f, 0.0f},  // 2^-125 = 128 2^(4 - 136): exponent byte 4
      {0.99999f, 0.5f, 0.0f},                // rounds to 256: one more exponent
      {std::ldexp(1.0f, 126), 0.0f, 0.0f},   // 128 2^(255 - 136): the largest exponent byte
      {std::ldexp(1.0f, 127), 0.0f, 0.0f},   // beyond RGBE: saturates
      {nan, 1.0f, 0.0f},                     // NaN -> 0 (encode_radiance only: write_image refuses it)
      {inf, 1.0f, 0.0f},                     // +Inf saturates (likewise)
  };
  const std::vector<std::array<int, 4>> expected = {{0, 0, 0, 0},         {0, 128, 0, 129},  {0, 0, 0, 0},
                                                    {128, 0, 0, 4},       {128, 64, 0, 129}, {128, 0, 0, 255},
                                                    {255, 255, 255, 255}, {0, 128, 0, 129},  {255, 255, 255, 255}};
  Image img(1, static_cast<int>(texels.size()), 3);  // width 1: flat scanlines, the RGBE bytes as they are
  img.channel_names = {"R", "G", "B"};
  for (std::size_t y = 0; y < texels.size(); ++y)
    for (int c = 0; c < 3; ++c) img.at(0, static_cast<int>(y), c) = texels[y][static_cast<std::size_t>(c)];
  const std::string bytes = encoded_pixels(img);
  ASSERT_EQ(bytes.size(), 4 * texels.size());
  for (std::size_t y = 0; y < texels.size(); ++y)
    for (std::size_t c = 0; c < 4; ++c)
      EXPECT_EQ(static_cast<unsigned char>(bytes[4 * y + c]), expected[y][c]) << "texel " << y << " byte " << c;
  // write_image keeps refusing non-finite images.
  EXPECT_NE(error_of([&] { envkit::write_image(path("nan.hdr"), img); }).find("non-finite"), std::string::npos);
}

TEST_F(HdrIoTest, EncodedBytesDoNotDependOnTheThreadCount) {
  // 2100 rows of 64 texels: several bands of blocks; 4099 x 40: wide rows, few per block.
  for (const auto& [w, h] : {std::pair{64, 2100}, std::pair{4099, 40}, std::pair{5, 300}}) {
    const Image img = encoder_cases(w, h);
    const std::vector<unsigned char> all = envkit::encode_radiance(img);
    std::vector<unsigned char> one, two;
    tbb::task_arena(1).execute([&] { one = envkit::encode_radiance(img); });
    tbb::task_arena(2).execute([&] { two = envkit::encode_radiance(img); });
    EXPECT_EQ(all, one) << w;
    EXPECT_EQ(all, two) << w;
    envkit::write_image(path("all.hdr"), img);
    tbb::task_arena(1).execute([&] { envkit::write_image(path("one.hdr"), img); });
    EXPECT_EQ(read_bytes(path("all.hdr")), read_bytes(path("one.hdr"))) << w;
  }
}

TEST_F(HdrIoTest, WrittenFilesReadBackInEnvkitAndOpenImageIOWithinRgbePrecision) {
  for (const int w : {1, 7, 8, 9, 129, 4099, 32767, 32768}) {
    Image img = encoder_cases(w, w > 5000 ? 5 : 12);
    for (float& v : img.pixels) v = std::min(std::max(v, 0.0f), 1e30f);  // write_image's values: finite
    envkit::write_image(path("w.hdr"), img);
    const Image ours = envkit::read_image(path("w.hdr"));
    auto in = OIIO::ImageInput::open(path("w.hdr"));
    ASSERT_TRUE(in) << OIIO::geterror();
    ASSERT_EQ(in->spec().width, w);
    ASSERT_EQ(in->spec().height, img.height);
    std::vector<float> theirs(img.pixels.size());
    ASSERT_TRUE(in->read_image(0, 0, 0, 3, OIIO::TypeDesc::FLOAT, theirs.data())) << in->geterror();
    ASSERT_EQ(ours.pixels.size(), theirs.size());
    for (std::size_t t = 0; t < img.texel_count(); ++t) {
      const float* a = &img.pixels[3 * t];
      const float m = std::max({a[0], a[1], a[2]});
      for (std::size_t c = 0; c < 3; ++c) {
        const std::size_t i = 3 * t + c;
        // OIIO 2.4 decodes some large exponents 1 ulp off the exact m 2^(e - 136) (e.g. 192 2^90 as 0x1.7ffffep+97):
        // the same value, not the same float.
        ASSERT_NEAR(ours.pixels[i], theirs[i], std::abs(ours.pixels[i]) * 0x1p-21f) << "width " << w << " texel " << t;
        // Half a mantissa step: 2^-8 of the largest component, up to 1/255.5 of it when rounding carried into the
        // next exponent (image_codecs.h promises 1/255); black below 1e-38.
        if (m >= 1e-38f)
          ASSERT_LE(std::abs(ours.pixels[i] - a[c]), m / 255.0f) << "width " << w << " texel " << t;
        else
          ASSERT_EQ(ours.pixels[i], 0.0f);
      }
    }
  }
}

TEST_F(HdrIoTest, MetadataOfEnvkitIsKeptInTheHeader) {
  Image img = exact_picture(16, 8);
  img.metadata["envkit:parameterization"] = "latlong";
  envkit::write_image(path("m.hdr"), img);
  const Image back = envkit::read_image(path("m.hdr"));
  EXPECT_EQ(back.metadata.at("envkit:parameterization"), "latlong");
  EXPECT_EQ(back.pixels, img.pixels);
}

// ---- header values --------------------------------------------------------------------------------------------------

TEST_F(HdrIoTest, ExposureAndColorcorrAreDividedOut) {
  std::string file =
      "#?RADIANCE\nEXPOSURE=2\nEXPOSURE= 2\nCOLORCORR=1 2 "
      "0.5\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 1\n" +
      rgbe(128, 128, 128, 132);  // 8, 8, 8
  write_bytes(path("exp.hdr"), file);
  envkit::ReadReport report;
  const Image img = envkit::read_image(path("exp.hdr"), {}, &report);
  EXPECT_FLOAT_EQ(img.at(0, 0, 0), 2.0f);  // 8 / (2 * 2 * 1)
  EXPECT_FLOAT_EQ(img.at(0, 0, 1), 1.0f);
  EXPECT_FLOAT_EQ(img.at(0, 0, 2), 4.0f);
  EXPECT_NE(report.summary().find("EXPOSURE"), std::string::npos) << report.summary();
}

TEST_F(HdrIoTest, XyzeIsConvertedToRec709) {
  // Published matrices (Bruce Lindbloom): Bradford from illuminant E to D65, and XYZ(D65) -> linear sRGB.
  const double bradford_e_d65[9] = {0.9531874, -0.0265906, 0.0238731,  -0.0382467, 1.0288406,
                                    0.0094060, 0.0026068,  -0.0030332, 1.0892565};
  const double xyz_to_srgb[9] = {3.2404542, -1.5371385, -0.4985314, -0.9692660, 1.8760108,
                                 0.0415560, 0.0556434,  -0.2040259, 1.0572252};
  auto times = [](const double* m, const double* v, double* out) {
    for (int i = 0; i < 3; ++i) out[i] = m[3 * i] * v[0] + m[3 * i + 1] * v[1] + m[3 * i + 2] * v[2];
  };
  std::string file = "#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 2\n";
  file += rgbe(128, 128, 128, 129);  // X = Y = Z = 1: Radiance's white
  file += rgbe(200, 100, 50, 128);   // 0.78125, 0.390625, 0.1953125
  write_bytes(path("xyz.hdr"), file);
  envkit::ReadReport report;
  const Image img = envkit::read_image(path("xyz.hdr"), {}, &report);
  ASSERT_EQ(img.channels, 3);
  EXPECT_EQ(img.channel_names, (std::vector<std::string>{"R", "G", "B"}));
  EXPECT_EQ(report.pixel_type, "xyze");
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(img.at(0, 0, c), 1.0f, 1e-4f) << "white stays white, channel " << c;
  const double xyz[3] = {0.78125, 0.390625, 0.1953125};
  double adapted[3], rgb[3];
  times(bradford_e_d65, xyz, adapted);
  times(xyz_to_srgb, adapted, rgb);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(img.at(1, 0, c), rgb[c], 1e-3) << c;
}

// ---- bad files ------------------------------------------------------------------------------------------------------

TEST_F(HdrIoTest, CorruptFilesGiveOneLineNamingTheFile) {
  const std::vector<std::string> row(16, rgbe(128, 128, 128, 129));
  const std::string good_rle = rle_dumps(row);
  std::string wrong_length = good_rle;
  wrong_length[3] = 15;
  std::string overflow = good_rle;
  overflow[4] = static_cast<char>(128 + 17);  // run of 17 in a 16-pixel scanline
  std::string dump_overflow = good_rle;
  dump_overflow[4] = 17;
  std::string zero = good_rle;
  zero[4] = 0;
  struct Case {
    const char* name;
    std::string bytes;
    const char* message;
  };
  const std::string res = "-Y 2 +X 16\n";
  const std::vector<Case> cases = {
      {"truncated_rle", kHeader + res + good_rle + good_rle.substr(0, 20), "scanline 1: data ends inside the scanline"},
      {"missing_scanline", kHeader + res + good_rle, "scanline 1: data ends before the scanline"},
      {"wrong_length", kHeader + res + wrong_length + good_rle,
       "scanline 0: run-length scanline of 15 pixels, expected 16"},
      {"run_overflow", kHeader + res + overflow + good_rle, "scanline 0: run of 17 overflows the scanline"},
      {"dump_overflow", kHeader + res + dump_overflow + good_rle, "scanline 0: run of 17 overflows the scanline"},
      {"zero_run", kHeader + res + zero + good_rle, "scanline 0: zero-length run"},
      {"repeat_first", kHeader + "-Y 1 +X 4\n" + rgbe(1, 1, 1, 2) + rgbe(1, 1, 1, 2),
       "repeat code with no previous pixel"},
      {"old_overflow", kHeader + "-Y 1 +X 4\n" + rgbe(9, 9, 9, 9) + rgbe(1, 1, 1, 4),
       "run of 4 overflows the scanline"},
      {"bad_format", "#?RADIANCE\nFORMAT=32-bit_rle_foo\n\n" + res, "unsupported Radiance FORMAT '32-bit_rle_foo'"},
      {"bad_resolution", kHeader + "-Y 2 -Y 16\n", "bad Radiance resolution string '-Y 2 -Y 16'"},
      {"negative_size", kHeader + "-Y -2 +X 16\n", "bad Radiance resolution string"},
      {"no_resolution", kHeader, "truncated Radiance header"},
      {"bad_exposure", "#?RADIANCE\nEXPOSURE=0\n\n" + res, "bad EXPOSURE line '0'"},
      {"endless_header", "#?RADIANCE\n" + std::string(envkit::kRadianceMaxHeaderBytes + 10, 'x'),
       "header longer than 1 MiB"},
      {"zero_size", kHeader + "-Y 0 +X 16\n", "bad Radiance resolution string"},
      {"huge", kHeader + "-Y 100000 +X 100000\n", "image too large: 100000x100000 = 10000000000 texels"},
  };
  for (const Case& c : cases) {
    const std::string file = path(std::string(c.name) + ".hdr");
    write_bytes(file, c.bytes);
    const std::string msg = error_of([&] { envkit::read_image(file); });
    EXPECT_EQ(msg.rfind(file + ": ", 0), 0u) << c.name << ": " << msg;
    EXPECT_NE(msg.find(c.message), std::string::npos) << c.name << ": " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << c.name;
  }
}

TEST_F(HdrIoTest, RandomGarbageAfterAHeaderIsRefusedOrDecodedNeverCrashes) {
  std::mt19937 rng(77);
  for (int trial = 0; trial < 200; ++trial) {
    std::string bytes = kHeader + "-Y 4 +X 12\n";
    const int n = static_cast<int>(rng() % 300);
    for (int i = 0; i < n; ++i) bytes += static_cast<char>(rng() % 4 == 0 ? 2 : rng() & 0xff);
    const std::span<const unsigned char> span(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size());
    try {
      const envkit::RadianceHeader h = envkit::parse_radiance_header(span, "g.hdr");
      const Image img = envkit::decode_radiance(span, h, "g.hdr");
      ASSERT_EQ(img.pixels.size(), std::size_t(4 * 12 * 3));
      for (float v : img.pixels) ASSERT_TRUE(std::isfinite(v) && v >= 0.0f);
    } catch (const Error& e) {
      ASSERT_EQ(std::string(e.what()).rfind("g.hdr: ", 0), 0u) << e.what();
    }
  }
}

// ---- PFM ------------------------------------------------------------------------------------------------------------

TEST_F(HdrIoTest, BigEndianPfmReads) {
  std::string bytes = "PF\n2 1\n1.0\n";
  const float values[6] = {1.0f, -2.0f, 3.5f, 1e30f, 0.25f, -0.0f};
  for (float v : values) {
    unsigned char b[4];
    std::memcpy(b, &v, 4);
    for (int k = 3; k >= 0; --k) bytes += static_cast<char>(b[k]);
  }
  write_bytes(path("be.pfm"), bytes);
  envkit::ReadReport report;
  const Image img = envkit::read_image(path("be.pfm"), {}, &report);
  EXPECT_EQ(report.format, "pfm");
  ASSERT_EQ(img.channels, 3);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(img.pixels[static_cast<std::size_t>(i)], values[i]) << i;
}

TEST_F(HdrIoTest, PfmRowsFlipForOddAndEvenHeights) {
  for (int h : {1, 2, 3, 8}) {
    Image img(3, h, 1);
    img.channel_names = {"Y"};
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < 3; ++x) img.at(x, y, 0) = static_cast<float>(10 * y + x);
    envkit::write_image(path("f.pfm"), img);
    const std::string bytes = read_bytes(path("f.pfm"));
    const std::string header = "Pf\n3 " + std::to_string(h) + "\n-1.0\n";
    ASSERT_EQ(bytes.substr(0, header.size()), header);
    float first;
    std::memcpy(&first, bytes.data() + header.size(), 4);
    EXPECT_EQ(first, static_cast<float>(10 * (h - 1))) << "the file starts with the bottom row";
    EXPECT_EQ(envkit::read_image(path("f.pfm")).pixels, img.pixels) << h;
  }
}

TEST_F(HdrIoTest, BadPfmFilesAreRefused) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"PF\n2 2\n-1.0\n" + std::string(20, '\0'), "48 bytes of pixels expected, 20 found"},
      {"PF\n2 x\n-1.0\n", "bad PFM height 'x'"},
      {"PF\n2 2\n0\n", "bad PFM scale '0'"},
      {"PF\n2 2\nnan\n", "bad PFM scale"},
      {"PF\n2 -2\n-1\n", "bad PFM height '-2'"},
      {"PF\n8 -0\n.14\n" + std::string(64, '\1'), "bad PFM height '-0'"},  // empty images (fuzz_codecs)
      {"Pf\n0 3\n-1\n", "bad PFM width '0'"},
      {"PF\n2", "truncated PFM header"},
  };
  for (const auto& [bytes, message] : cases) {
    write_bytes(path("bad.pfm"), bytes);
    const std::string msg = error_of([&] { envkit::read_image(path("bad.pfm")); });
    EXPECT_EQ(msg.rfind(path("bad.pfm") + ": ", 0), 0u) << msg;
    EXPECT_NE(msg.find(message), std::string::npos) << msg;
  }
}

// ---- non-regular inputs and limits ----------------------------------------------------------------------------------

TEST_F(HdrIoTest, FifosDevicesAndDirectoriesAreRefusedWithoutBlocking) {
  const std::string fifo = path("pipe.hdr");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(error_of([&] { envkit::read_image(fifo); }),
            fifo + ": is a FIFO, not a regular file (envkit reads regular files only)");
  EXPECT_EQ(error_of([&] { envkit::read_image("/dev/zero"); }),
            "/dev/zero: is a character device, not a regular file (envkit "
            "reads regular files only)");
  fs::create_directory(path("d.exr"));
  EXPECT_EQ(error_of([&] { envkit::read_image(path("d.exr")); }), path("d.exr") + ": is a directory");
  EXPECT_EQ(error_of([&] { envkit::read_image(path("none.exr")); }), path("none.exr") + ": no such file");
  EXPECT_EQ(error_of([&] { envkit::read_regular_file(fifo, 100); }),
            fifo + ": is a FIFO, not a regular file (envkit reads regular files only)");
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5)) << "a reader blocked";
}

TEST_F(HdrIoTest, BuffersBeyondTheMachinesMemoryAreRefusedNamingTheFileAndSize) {
  const std::uint64_t available = envkit::available_memory_bytes();
  ASSERT_GT(available, std::uint64_t(1) << 20);
  EXPECT_NO_THROW(envkit::check_memory_for("a.exr", "image 4x4", 192));
  const std::string msg = error_of([&] { envkit::check_memory_for("a.exr", "image too large: 1x1", available + 1); });
  EXPECT_EQ(msg.rfind("a.exr: image too large: 1x1 needs ", 0), 0u) << msg;
  EXPECT_NE(msg.find(" GiB available"), std::string::npos) << msg;
}

// ---- OpenImageIO and libhealpix only on demand -------------------------------------------------------------

/// Whether `envconvert args` (which must succeed) loads a shared library whose name contains `library`: the dynamic
/// loader lists every library it opens under LD_DEBUG=files.
bool envconvert_loads(const std::string& library, const std::vector<std::string>& args, const std::string& dir) {
  std::vector<std::string> a = {"LD_DEBUG=files", std::string(ENVKIT_BIN_DIR) + "/envconvert"};
  a.insert(a.end(), args.begin(), args.end());
  const envkit::test::CommandResult r = envkit::test::run_command("/usr/bin/env", a, dir);
  EXPECT_EQ(r.code, 0) << r.err.substr(r.err.size() > 2000 ? r.err.size() - 2000 : 0);
  return r.err.find(library) != std::string::npos;
}

TEST_F(HdrIoTest, ExrHdrPfmAndPngRunsNeverLoadOpenImageIO) {
  envkit::write_image(path("a.exr"), exact_picture(16, 8));
  auto loads_oiio = [&](const std::vector<std::string>& args) {
    return envconvert_loads("libOpenImageIO", args, dir_);
  };
  EXPECT_FALSE(loads_oiio({path("a.exr"), "-o", path("b.hdr"), "--to", "latlong", "--from", "latlong", "-q"}));
  EXPECT_FALSE(loads_oiio({path("b.hdr"), "-o", path("c.pfm"), "--to", "latlong", "--from", "latlong", "-q"}));
  EXPECT_FALSE(loads_oiio({path("c.pfm"), "-o", path("d.exr"), "--to", "cube", "--from", "latlong", "-q"}));
  // PNG goes through libpng in libenv, both ways.
  EXPECT_FALSE(loads_oiio({path("a.exr"), "-o", path("e.png"), "--to", "latlong", "--from", "latlong", "-q"}));
  EXPECT_FALSE(loads_oiio({path("e.png"), "-o", path("f.exr"), "--to", "latlong", "--from", "latlong", "-q"}));
  // A TIFF needs the module: loaded then, and the file is written.
  EXPECT_TRUE(loads_oiio({path("a.exr"), "-o", path("g.tif"), "--to", "latlong", "--from", "latlong", "-q"}));
  EXPECT_TRUE(fs::exists(path("g.tif")));
}

// OpenColorIO and parsing its config cost every run about 9 ms: float files in the working space never load it.
TEST_F(HdrIoTest, OnlyColourConversionsLoadOpenColorIO) {
  envkit::write_image(path("a.exr"), exact_picture(16, 8));
  auto loads_ocio = [&](const std::vector<std::string>& args) {
    return envconvert_loads("libOpenColorIO", args, dir_);
  };
  EXPECT_FALSE(loads_ocio({path("a.exr"), "-o", path("b.exr"), "--to", "cube", "--from", "latlong", "-q"}));
  EXPECT_FALSE(loads_ocio({path("b.exr"), "-o", path("c.hdr"), "--to", "latlong", "-q"}));
  EXPECT_FALSE(loads_ocio({path("c.hdr"), "-o", path("d.pfm"), "--to", "latlong", "--from", "latlong", "-q"}));
  // An 8-bit PNG holds sRGB-encoded values: encoding them needs OpenColorIO, and the file is written.
  EXPECT_TRUE(loads_ocio({path("a.exr"), "-o", path("e.png"), "--to", "latlong", "--from", "latlong", "-q"}));
  EXPECT_TRUE(fs::exists(path("e.png")));
  // A space the table does not hold goes to OpenColorIO too.
  EXPECT_TRUE(loads_ocio(
      {path("a.exr"), "-o", path("f.exr"), "--to", "latlong", "--from", "latlong", "--colorspace", "acescg", "-q"}));
}

// libhealpix-cxx brings cfitsio, curl and GnuTLS, whose start-up every run would pay: only HEALPix maps load it.
TEST_F(HdrIoTest, OnlyHealpixRunsLoadLibhealpix) {
  envkit::write_image(path("a.exr"), exact_picture(16, 8));
  auto loads_healpix = [&](const std::vector<std::string>& args) { return envconvert_loads("libhealpix", args, dir_); };
  EXPECT_FALSE(loads_healpix({path("a.exr"), "-o", path("b.exr"), "--to", "cube", "--from", "latlong", "-q"}));
  EXPECT_TRUE(loads_healpix({path("a.exr"), "-o", path("h.exr"), "--to", "healpix", "--from", "latlong", "-q"}));
  // Reading it back (a HEALPix map by its metadata) loads the module too.
  EXPECT_TRUE(loads_healpix({path("h.exr"), "-o", path("c.exr"), "--to", "latlong", "-q"}));
}

}  // namespace
