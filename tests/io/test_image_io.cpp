// Tests for image_io.h: round trips per format with stated bounds, colour decoding, non-finite policies,
// error messages, size guards, atomic writes and the OpenEXR envmap attribute.
// Special input files (NaN, 7 channels, chromaticities, multi-part) are crafted with OIIO directly or by hand.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfEnvmapAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <OpenEXR/ImfRgbaFile.h>
#include <OpenImageIO/imageio.h>
#include <envkit/core/error.h>
#include <envkit/core/image.h>
#include <envkit/io/image_io.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using envkit::ClampReport;
using envkit::Error;
using envkit::Image;
using envkit::NonFinitePolicy;
using envkit::PixelType;
using envkit::ReadOptions;
using envkit::ReadReport;
using envkit::WriteOptions;

namespace {

double srgb_oetf(double l) {
  l = std::clamp(l, 0.0, 1.0);
  return l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1.0 / 2.4) - 0.055;
}

/// Deterministic HDR-ish test image: colour in [lo, hi], alpha (if any) in [0, 1].
Image test_image(int w, int h, int c, unsigned seed, float lo = 0.0f, float hi = 8.0f) {
  Image img(w, h, c);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> colour(lo, hi), alpha(0.0f, 1.0f);
  for (std::size_t t = 0; t < img.texel_count(); ++t)
    for (int k = 0; k < c; ++k) img.pixels[t * c + k] = k == img.alpha_channel ? alpha(rng) : colour(rng);
  return img;
}

/// Writes float pixels with OIIO directly (for files envkit itself refuses to write).
void write_with_oiio(const std::string& path, int w, int h, const std::vector<std::string>& names,
                     const std::vector<float>& pixels, const std::function<void(OIIO::ImageSpec&)>& edit = {}) {
  OIIO::ImageSpec spec(w, h, static_cast<int>(names.size()), OIIO::TypeDesc::FLOAT);
  spec.channelnames = names;
  if (edit) edit(spec);
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out) << OIIO::geterror();
  ASSERT_TRUE(out->open(path, spec)) << out->geterror();
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, pixels.data())) << out->geterror();
  ASSERT_TRUE(out->close());
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// Runs a shell command, returning its stdout and exit code.
std::string run(const std::string& cmd, int* code = nullptr) {
  std::string output;
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (!pipe) return output;
  char buffer[4096];
  while (std::size_t n = std::fread(buffer, 1, sizeof buffer, pipe)) output.append(buffer, n);
  const int status = ::pclose(pipe);
  if (code) *code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return output;
}

long max_rss_kb() {
  rusage usage{};
  ::getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

bool starts_with(const std::string& s, const std::string& prefix) { return s.rfind(prefix, 0) == 0; }

class ImageIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ::unsetenv("OCIO");  // the expectations below describe envkit's shipped config
    ::unsetenv("ENVKIT_OCIO_CONFIG");
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("envkit_io_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::vector<std::string> listing() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
    return names;
  }
  fs::path dir_;
};

void expect_same_layout(const Image& a, const Image& b) {
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  ASSERT_EQ(a.channels, b.channels);
  EXPECT_EQ(a.alpha_channel, b.alpha_channel);
  EXPECT_EQ(a.channel_names, b.channel_names);
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
}

}  // namespace

// ---- round trips ------------------------------------------------------------------------------------------

TEST_F(ImageIoTest, FloatExrRoundTripIsExactForEveryLayout) {
  for (int c = 1; c <= 4; ++c) {
    const Image img = test_image(37, 23, c, 100u + static_cast<unsigned>(c), -1.0f, 1000.0f);
    const std::string file = path("float" + std::to_string(c) + ".exr");
    envkit::write_image(file, img);
    ReadReport report;
    const Image back = envkit::read_image(file, {}, &report);
    expect_same_layout(back, img);
    EXPECT_EQ(back.pixels, img.pixels) << c << " channels";
    EXPECT_EQ(report.format, "openexr");
    EXPECT_EQ(report.pixel_type, "float");
    EXPECT_EQ(report.file_colorspace, "lin_rec709");
    EXPECT_FALSE(report.converted);
    EXPECT_EQ(back.metadata.at("compression"), "zip");
  }
}

TEST_F(ImageIoTest, HalfExrRoundTripWithinHalfPrecision) {
  Image img = test_image(64, 32, 4, 7, 0.0f, 60000.0f);
  img.pixels[0] = 1.0e6f;  // beyond half range: clamped, not Inf
  WriteOptions opt;
  opt.pixel_type = PixelType::Half;
  envkit::write_image(path("half.exr"), img, opt);
  ReadReport report;
  const Image back = envkit::read_image(path("half.exr"), {}, &report);
  EXPECT_EQ(report.pixel_type, "half");
  expect_same_layout(back, img);
  EXPECT_EQ(back.pixels[0], 65504.0f);
  for (std::size_t i = 1; i < img.pixels.size(); ++i) {
    const float a = img.pixels[i];
    // 11 significant bits: relative error <= 2^-11 after rounding; absolute 2^-25 in the subnormal range.
    EXPECT_NEAR(back.pixels[i], a, std::abs(a) * 0x1p-11f + 0x1p-25f) << i;
  }
}

TEST_F(ImageIoTest, HalfExrLargerThanOneConversionBlock) {
  // Half data is converted and written a block of rows at a time: an image of several blocks and a remainder
  // (16 MiB of halves per block: 682 rows of 4097 RGB texels) must come back row for row.
  const int w = 4097, h = 1500;
  Image img(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c)  // integers below 2048: exact in half
        img.pixels[(std::size_t(y) * w + x) * 3 + c] = float((x + 7 * y + 500 * c) % 2048);
  Image expected = img;
  img.pixels[(std::size_t(700) * w + 5) * 3] = -1.0e6f;         // second block
  img.pixels[(std::size_t(1499) * w + 4096) * 3 + 2] = 1.0e6f;  // last row of the remainder
  expected.pixels[(std::size_t(700) * w + 5) * 3] = -65504.0f;
  expected.pixels[(std::size_t(1499) * w + 4096) * 3 + 2] = 65504.0f;
  WriteOptions opt;
  opt.pixel_type = PixelType::Half;
  opt.compression = "none";
  const ClampReport clamped = envkit::write_image(path("blocks.exr"), img, opt);
  const Image back = envkit::read_image(path("blocks.exr"));
  expect_same_layout(back, expected);
  EXPECT_TRUE(back.pixels == expected.pixels);
  // Both values beyond half's range are reported, in magnitude, and nothing else.
  EXPECT_EQ(clamped.format, "half");
  EXPECT_EQ(clamped.above, 2u);
  EXPECT_EQ(clamped.largest, 1.0e6);
  EXPECT_EQ(clamped.negative, 0u);
}

TEST_F(ImageIoTest, HalfWritesReportWhatTheyClampAndFloatWritesNothing) {
  Image img(8, 4, 4);  // RGBA: written through a channel selection, not straight from the pixels
  std::fill(img.pixels.begin(), img.pixels.end(), 1.0f);
  img.alpha_channel = 3;
  img.at(1, 1, 0) = 65504.0f;  // half's largest: held exactly, not clamped
  img.at(2, 1, 1) = 65505.0f;
  img.at(3, 2, 2) = 3.5e7f;
  img.at(4, 3, 0) = -8.0e5f;
  img.at(5, 3, 1) = -3.0f;  // negative but within half's range
  WriteOptions opt;
  opt.pixel_type = PixelType::Half;
  const ClampReport clamped = envkit::write_image(path("sun_half.exr"), img, opt);
  EXPECT_EQ(clamped.above, 3u);
  EXPECT_EQ(clamped.largest, double(3.5e7f));
  EXPECT_EQ(clamped.negative, 0u);
  EXPECT_EQ(clamped.message("sun.exr"),
            "sun.exr: 3 values above half's largest 65504 were clamped (largest 3.5e+07); use a float output to keep "
            "the sun");
  EXPECT_FALSE(envkit::write_image(path("sun_float.exr"), img).any());
  // Radiance holds the sun but no sign: the negative colour values are reported (alpha is not written).
  const ClampReport rgbe = envkit::write_image(path("sun.hdr"), img);
  EXPECT_EQ(rgbe.format, "rgbe");
  EXPECT_EQ(rgbe.above, 0u);
  EXPECT_EQ(rgbe.negative, 2u);
  EXPECT_EQ(rgbe.lowest, double(-8.0e5f));
}

TEST_F(ImageIoTest, HdrRoundTripWithinRgbePrecision) {
  const Image img = test_image(40, 20, 3, 11, 0.001f, 50.0f);
  envkit::write_image(path("rgbe.hdr"), img);
  ReadReport report;
  const Image back = envkit::read_image(path("rgbe.hdr"), {}, &report);
  EXPECT_EQ(report.format, "hdr");
  EXPECT_EQ(report.file_colorspace, "lin_rec709");
  ASSERT_EQ(back.channels, 3);
  for (std::size_t t = 0; t < img.texel_count(); ++t) {
    const float* a = &img.pixels[3 * t];
    const float m = std::max({a[0], a[1], a[2]});
    // RGBE: 8-bit mantissas sharing the exponent of the largest component -> error <= ~1% of that component.
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(back.pixels[3 * t + k], a[k], 0.01f * m) << t << "," << k;
  }
}

TEST_F(ImageIoTest, HdrStoresRgbOnly) {
  Image grey = test_image(8, 4, 2, 12, 0.5f, 2.0f);  // YA
  envkit::write_image(path("grey.hdr"), grey);
  const Image back = envkit::read_image(path("grey.hdr"));
  ASSERT_EQ(back.channels, 3);
  EXPECT_EQ(back.alpha_channel, -1);
  for (std::size_t t = 0; t < grey.texel_count(); ++t)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(back.pixels[3 * t + k], grey.pixels[2 * t], 0.01f * grey.pixels[2 * t]);
}

TEST_F(ImageIoTest, PfmRoundTripIsExact) {
  for (int c : {1, 3}) {
    const Image img = test_image(19, 7, c, 13u + static_cast<unsigned>(c), -5.0f, 5.0e4f);
    const std::string file = path("data" + std::to_string(c) + ".pfm");
    envkit::write_image(file, img);
    const Image back = envkit::read_image(file);
    ASSERT_EQ(back.channels, c);
    EXPECT_EQ(back.pixels, img.pixels);
  }
}

TEST_F(ImageIoTest, PfmRowsAreStoredBottomToTop) {
  // Hand-made 1x2 PFM: the first row in the file is the bottom of the image.
  std::string bytes = "Pf\n1 2\n-1.0\n";
  const float rows[2] = {1.0f, 2.0f};
  bytes.append(reinterpret_cast<const char*>(rows), sizeof rows);
  write_bytes(path("rows.pfm"), bytes);
  const Image img = envkit::read_image(path("rows.pfm"));
  ASSERT_EQ(img.height, 2);
  EXPECT_EQ(img.at(0, 0, 0), 2.0f) << "top row";
  EXPECT_EQ(img.at(0, 1, 0), 1.0f) << "bottom row";
  // And envkit writes the same convention.
  envkit::write_image(path("rows2.pfm"), img);
  std::ifstream in(path("rows2.pfm"), std::ios::binary);
  const std::string written((std::istreambuf_iterator<char>(in)), {});
  EXPECT_EQ(written, bytes);
}

TEST_F(ImageIoTest, FloatTiffRoundTripIsExact) {
  const Image img = test_image(33, 17, 4, 17, 0.0f, 100.0f);
  envkit::write_image(path("float.tif"), img);
  ReadReport report;
  const Image back = envkit::read_image(path("float.tif"), {}, &report);
  expect_same_layout(back, img);
  EXPECT_EQ(back.pixels, img.pixels);
  EXPECT_EQ(report.file_colorspace, "lin_rec709");
}

TEST_F(ImageIoTest, Png8BitRoundTripWithinOneCodeValueInSrgb) {
  const Image img = test_image(50, 30, 3, 19, 0.0f, 1.2f);  // includes values above 1: clipped
  envkit::write_image(path("preview.png"), img);
  ReadReport report;
  const Image back = envkit::read_image(path("preview.png"), {}, &report);
  EXPECT_EQ(report.pixel_type, "uint8");
  EXPECT_EQ(report.file_colorspace, "srgb");
  EXPECT_TRUE(report.converted);
  expect_same_layout(back, img);
  for (std::size_t i = 0; i < img.pixels.size(); ++i)
    EXPECT_NEAR(srgb_oetf(back.pixels[i]), srgb_oetf(img.pixels[i]), 1.0 / 255.0 + 1e-4) << i;
}

TEST_F(ImageIoTest, PngAlphaIsUnassociatedInTheFileAndPremultipliedInMemory) {
  // Premultiplied linear texels: colour = straight colour * alpha.
  Image img(4, 1, 4);
  const float straight[4] = {0.2158605f, 0.5f, 1.0f, 0.8f};
  const float alpha[4] = {1.0f, 0.5f, 0.25f, 0.0f};
  for (int x = 0; x < 4; ++x) {
    for (int c = 0; c < 3; ++c) img.at(x, 0, c) = straight[x] * alpha[x];
    img.at(x, 0, 3) = alpha[x];
  }
  img.at(3, 0, 0) = img.at(3, 0, 1) = img.at(3, 0, 2) = 0.0f;
  envkit::write_image(path("alpha.png"), img);

  // In the file: sRGB-encoded straight colour (what every PNG viewer expects).
  OIIO::ImageSpec keep_unassociated;
  keep_unassociated.attribute("oiio:UnassociatedAlpha", 1);
  auto in = OIIO::ImageInput::open(path("alpha.png"), &keep_unassociated);
  ASSERT_TRUE(in);
  std::vector<unsigned char> raw(16);
  ASSERT_TRUE(in->read_image(0, 0, 0, 4, OIIO::TypeDesc::UINT8, raw.data()));
  EXPECT_EQ(raw[0], 128);  // 0.2158605 linear at alpha 1
  EXPECT_NEAR(raw[4], 255.0 * srgb_oetf(0.5), 1.0) << "straight colour, not premultiplied";
  EXPECT_EQ(raw[8], 255);
  EXPECT_EQ(raw[7], 128);  // alpha 0.5 is not colour-encoded
  in.reset();

  // Back in memory: premultiplied again.
  const Image back = envkit::read_image(path("alpha.png"));
  for (int x = 0; x < 4; ++x) {
    EXPECT_NEAR(back.at(x, 0, 3), alpha[x], 1.0 / 255.0);
    EXPECT_NEAR(back.at(x, 0, 0), img.at(x, 0, 0), 0.01 * alpha[x] + 1e-6) << x;
  }
}

TEST_F(ImageIoTest, Png16BitRoundTrip) {
  const Image img = test_image(20, 10, 3, 23, 0.0f, 1.0f);
  WriteOptions opt;
  opt.pixel_type = PixelType::UInt16;
  envkit::write_image(path("deep.png"), img, opt);
  ReadReport report;
  const Image back = envkit::read_image(path("deep.png"), {}, &report);
  EXPECT_EQ(report.pixel_type, "uint16");
  for (std::size_t i = 0; i < img.pixels.size(); ++i)
    EXPECT_NEAR(srgb_oetf(back.pixels[i]), srgb_oetf(img.pixels[i]), 1.0 / 65535.0 + 2e-5) << i;
}

TEST_F(ImageIoTest, NetpbmRoundTripUsesRec709Encoding) {
  const Image img = test_image(9, 5, 3, 71, 0.0f, 1.0f);
  envkit::write_image(path("small.ppm"), img);
  ReadReport report;
  const Image back = envkit::read_image(path("small.ppm"), {}, &report);
  EXPECT_EQ(report.file_colorspace, "rec709");
  const auto oetf = [](double l) { return l < 0.018 ? 4.5 * l : 1.099 * std::pow(l, 0.45) - 0.099; };
  for (std::size_t i = 0; i < img.pixels.size(); ++i)
    EXPECT_NEAR(oetf(back.pixels[i]), oetf(img.pixels[i]), 1.0 / 255.0 + 2e-3) << i;  // 2e-3: OCIO's toe
}

TEST_F(ImageIoTest, JpegDropsAlphaAndEncodesSrgb) {
  Image img(16, 16, 4);
  for (std::size_t t = 0; t < img.texel_count(); ++t) {
    img.pixels[4 * t + 0] = img.pixels[4 * t + 1] = img.pixels[4 * t + 2] = 0.2158605f;
    img.pixels[4 * t + 3] = 1.0f;
  }
  envkit::write_image(path("flat.jpg"), img);
  const Image back = envkit::read_image(path("flat.jpg"));
  ASSERT_EQ(back.channels, 3);
  for (float v : back.pixels) EXPECT_NEAR(srgb_oetf(v), 128.0 / 255.0, 2.0 / 255.0);
}

// ---- colour decoding ------------------------------------------------------------------------------------

TEST_F(ImageIoTest, EightBitValue128DecodesWithTheSrgbEotf) {
  // An OIIO-written 8-bit PNG holding code value 128.
  OIIO::ImageSpec spec(2, 1, 3, OIIO::TypeDesc::UINT8);
  const unsigned char px[6] = {128, 128, 128, 128, 128, 128};
  auto out = OIIO::ImageOutput::create(path("mid.png"));
  ASSERT_TRUE(out->open(path("mid.png"), spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px));
  out.reset();
  ReadReport report;
  const Image img = envkit::read_image(path("mid.png"), {}, &report);
  EXPECT_EQ(report.file_colorspace, "srgb");
  for (float v : img.pixels) EXPECT_NEAR(v, 0.2158605, 1e-4);
}

TEST_F(ImageIoTest, NetpbmIsDecodedWithTheRec709Oetf) {
  // OIIO tags Netpbm files Rec709 (the transfer the Netpbm specification prescribes).
  write_bytes(path("mid.pgm"), std::string("P5\n1 1\n255\n") + static_cast<char>(128));
  ReadReport report;
  const Image img = envkit::read_image(path("mid.pgm"), {}, &report);
  EXPECT_EQ(report.file_colorspace, "rec709");
  EXPECT_NEAR(img.pixels[0], std::pow((128.0 / 255.0 + 0.099) / 1.099, 1.0 / 0.45), 1e-4);
}

TEST_F(ImageIoTest, EightBitIsNeverTakenAsLinear) {
  OIIO::ImageSpec spec(1, 1, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "Linear");  // PNG gAMA 1.0
  const unsigned char px[3] = {128, 128, 128};
  auto out = OIIO::ImageOutput::create(path("lin.png"));
  ASSERT_TRUE(out->open(path("lin.png"), spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px));
  out.reset();
  ReadReport report;
  const Image img = envkit::read_image(path("lin.png"), {}, &report);
  EXPECT_EQ(report.file_colorspace, "srgb");
  EXPECT_NEAR(img.pixels[0], 0.2158605, 1e-4);
  ASSERT_FALSE(report.notes.empty());
  EXPECT_NE(report.notes[0].find("8-bit"), std::string::npos) << report.notes[0];
}

TEST_F(ImageIoTest, GammaTaggedPngIsDecodedWithItsGamma) {
  OIIO::ImageSpec spec(1, 1, 1, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "GammaCorrected");
  spec.attribute("oiio:Gamma", 2.2f);
  const unsigned char px[1] = {128};
  auto out = OIIO::ImageOutput::create(path("g22.png"));
  ASSERT_TRUE(out->open(path("g22.png"), spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px));
  out.reset();
  ReadReport report;
  const Image img = envkit::read_image(path("g22.png"), {}, &report);
  EXPECT_EQ(report.file_colorspace, "gamma 2.2");
  EXPECT_NEAR(img.pixels[0], std::pow(128.0 / 255.0, 2.2), 1e-4);
}

TEST_F(ImageIoTest, ExplicitColorspaceOptionWins) {
  write_bytes(path("mid.pgm"), std::string("P5\n1 1\n255\n") + static_cast<char>(128));
  ReadOptions raw;
  raw.colorspace = "raw";
  EXPECT_NEAR(envkit::read_image(path("mid.pgm"), raw).pixels[0], 128.0 / 255.0, 1e-6);
  ReadOptions bogus;
  bogus.colorspace = "bogus";
  const std::string msg = error_of([&] { envkit::read_image(path("mid.pgm"), bogus); });
  EXPECT_TRUE(starts_with(msg, path("mid.pgm") + ": unknown colour space 'bogus'")) << msg;
}

TEST_F(ImageIoTest, AcesChromaticitiesAreDetectedAndConverted) {
  const std::vector<float> red = {1, 0, 0};
  write_with_oiio(path("ap1.exr"), 1, 1, {"R", "G", "B"}, red, [](OIIO::ImageSpec& spec) {
    const float ap1[8] = {0.713f, 0.293f, 0.165f, 0.830f, 0.128f, 0.044f, 0.32168f, 0.33767f};
    spec.attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8), ap1);
  });
  ReadReport report;
  const Image img = envkit::read_image(path("ap1.exr"), {}, &report);
  EXPECT_EQ(report.file_colorspace, "acescg");
  EXPECT_TRUE(report.converted);
  EXPECT_NEAR(img.pixels[0], 1.70505, 1e-3);
  EXPECT_NEAR(img.pixels[1], -0.13026, 1e-3);
  EXPECT_NEAR(img.pixels[2], -0.02400, 1e-3);
  EXPECT_EQ(report.negative_count, 2u) << "wide-gamut red is outside Rec.709";

  // The same through the option on an untagged file.
  write_with_oiio(path("plain.exr"), 1, 1, {"R", "G", "B"}, red);
  ReadOptions opt;
  opt.colorspace = "ACEScg";
  EXPECT_NEAR(envkit::read_image(path("plain.exr"), opt).pixels[0], 1.70505, 1e-3);
}

// ---- non-finite and negative values --------------------------------------------------------------------------

class NonFiniteTest : public ImageIoTest {
 protected:
  void SetUp() override {
    ImageIoTest::SetUp();
    // 4x2 RGB: 3 NaN, 5 +Inf, 4 -Inf, 2 negative finite values.
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    pixels_ = {nan,  1.0f, 2.0f, inf,  3.0f, -inf, 0.5f, nan,   inf,  -1.0f, 4.0f, 6.0f,
               -inf, inf,  -inf, 7.0f, 8.0f, inf,  nan,  -2.0f, -inf, 9.0f,  inf,  5.0f};
    write_with_oiio(file_ = path("bad.exr"), 4, 2, {"R", "G", "B"}, pixels_);
  }
  std::vector<float> pixels_;
  std::string file_;
};

TEST_F(NonFiniteTest, ErrorPolicyThrowsWithCounts) {
  EXPECT_EQ(error_of([&] { envkit::read_image(file_); }),
            file_ + ": 12 non-finite values (3 NaN, 9 Inf); pass --fix-nonfinite zero|clamp");
}

TEST_F(NonFiniteTest, ZeroPolicyReplacesEverythingByZero) {
  ReadOptions opt;
  opt.nonfinite = NonFinitePolicy::Zero;
  ReadReport report;
  const Image img = envkit::read_image(file_, opt, &report);
  EXPECT_EQ(report.nan_count, 3u);
  EXPECT_EQ(report.posinf_count, 5u);
  EXPECT_EQ(report.neginf_count, 4u);
  EXPECT_EQ(report.replaced_count, 12u);
  EXPECT_EQ(report.negative_count, 2u);
  for (std::size_t i = 0; i < pixels_.size(); ++i)
    EXPECT_EQ(img.pixels[i], std::isfinite(pixels_[i]) ? pixels_[i] : 0.0f) << i;
}

TEST_F(NonFiniteTest, ClampPolicyUsesTheChannelMaximumForPositiveInfinity) {
  ReadOptions opt;
  opt.nonfinite = NonFinitePolicy::Clamp;
  const Image img = envkit::read_image(file_, opt);
  // Largest finite value per channel, read off the data above.
  float channel_max[3] = {-1e30f, -1e30f, -1e30f};
  for (std::size_t i = 0; i < pixels_.size(); ++i)
    if (std::isfinite(pixels_[i])) channel_max[i % 3] = std::max(channel_max[i % 3], pixels_[i]);
  EXPECT_EQ(channel_max[0], 9.0f);
  for (std::size_t i = 0; i < pixels_.size(); ++i) {
    const float v = pixels_[i];
    const float expected = std::isnan(v) ? 0.0f : std::isinf(v) ? (v > 0 ? channel_max[i % 3] : 0.0f) : v;
    EXPECT_EQ(img.pixels[i], expected) << i;
  }
  EXPECT_EQ(envkit::parse_nonfinite_policy("clamp"), NonFinitePolicy::Clamp);
  EXPECT_THROW(envkit::parse_nonfinite_policy("fix"), Error);
}

// The read counts the file's NaN, +Inf, -Inf and negative values in one pass, and counts the negatives again only
// when a later step changed the values. Checked against counts taken value by value, on images large enough for many
// blocks and parallel ranges, with the special values scattered at random and -0 (not negative) among them.
struct BruteCounts {
  std::size_t nan = 0, posinf = 0, neginf = 0, negative = 0;
};

BruteCounts brute_counts(std::span<const float> v) {
  BruteCounts c;
  for (const float x : v) {
    if (std::isnan(x))
      ++c.nan;
    else if (x == std::numeric_limits<float>::infinity())
      ++c.posinf;
    else if (x == -std::numeric_limits<float>::infinity())
      ++c.neginf;
    if (x < 0.0f) ++c.negative;  // -Inf included, NaN and -0 not
  }
  return c;
}

std::vector<float> speckled_values(std::size_t n, unsigned seed, bool nonfinite) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> value(-0.5f, 8.0f);
  std::uniform_int_distribution<int> kind(0, 999);
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<float> v(n);
  for (float& x : v) {
    const int k = kind(rng);
    x = value(rng);
    if (k < 3) x = -0.0f;
    if (nonfinite && k >= 3 && k < 5) x = std::numeric_limits<float>::quiet_NaN();
    if (nonfinite && k >= 5 && k < 7) x = inf;
    if (nonfinite && k >= 7 && k < 8) x = -inf;
  }
  return v;
}

TEST_F(ImageIoTest, OnePassCountsMatchValueByValueCounts) {
  const int w = 301, h = 217;  // 195,951 values: many 4096-value blocks and several parallel ranges, odd ends
  // Finite values, no conversion: the negatives come from the one pass.
  const std::vector<float> finite = speckled_values(std::size_t(w) * h * 3, 5, false);
  write_with_oiio(path("finite.exr"), w, h, {"R", "G", "B"}, finite);
  ReadReport report;
  Image img = envkit::read_image(path("finite.exr"), {}, &report);
  const BruteCounts f = brute_counts(finite);
  ASSERT_GT(f.negative, 1000u);
  EXPECT_EQ(report.nonfinite_count(), 0u);
  EXPECT_EQ(report.negative_count, f.negative);
  EXPECT_EQ(brute_counts(std::span<const float>(img.pixels.data(), img.pixels.size())).negative, f.negative);

  // NaN and Inf replaced by each policy: the file's counts, then the negatives of the pixels returned.
  const std::vector<float> speckled = speckled_values(std::size_t(w) * h * 3, 6, true);
  write_with_oiio(path("speckled.exr"), w, h, {"R", "G", "B"}, speckled);
  const BruteCounts b = brute_counts(speckled);
  ASSERT_GT(b.nan, 100u);
  ASSERT_GT(b.neginf, 100u);
  for (const NonFinitePolicy policy : {NonFinitePolicy::Zero, NonFinitePolicy::Clamp}) {
    ReadOptions opt;
    opt.nonfinite = policy;
    img = envkit::read_image(path("speckled.exr"), opt, &report);
    EXPECT_EQ(report.nan_count, b.nan);
    EXPECT_EQ(report.posinf_count, b.posinf);
    EXPECT_EQ(report.neginf_count, b.neginf);
    EXPECT_EQ(report.replaced_count, b.nan + b.posinf + b.neginf);
    EXPECT_EQ(report.negative_count, b.negative - b.neginf) << "-Inf is replaced by 0";
    EXPECT_EQ(report.negative_count,
              brute_counts(std::span<const float>(img.pixels.data(), img.pixels.size())).negative);
  }

  // A colour conversion changes the values: the negatives are those of the converted pixels.
  ReadOptions wide;
  wide.colorspace = "ACEScg";
  img = envkit::read_image(path("finite.exr"), wide, &report);
  EXPECT_TRUE(report.converted);
  const std::size_t converted_negative =
      brute_counts(std::span<const float>(img.pixels.data(), img.pixels.size())).negative;
  EXPECT_NE(converted_negative, f.negative);
  EXPECT_EQ(report.negative_count, converted_negative);

  // envkit's own codecs (PFM here, bottom row first) take the same path.
  std::string pfm = "PF\n" + std::to_string(w) + " " + std::to_string(h) + "\n-1.0\n";
  pfm.append(reinterpret_cast<const char*>(finite.data()), finite.size() * sizeof(float));
  write_bytes(path("finite.pfm"), pfm);
  envkit::read_image(path("finite.pfm"), {}, &report);
  EXPECT_EQ(report.format, "pfm");
  EXPECT_EQ(report.negative_count, f.negative);

  // count_nonfinite on spans of every length around a block's end.
  for (const std::size_t n :
       {std::size_t(0), std::size_t(1), std::size_t(4095), std::size_t(4096), std::size_t(4097), speckled.size()}) {
    const std::vector<float> part(speckled.begin(), speckled.begin() + std::ptrdiff_t(n));
    const BruteCounts p = brute_counts(part);
    const envkit::NonFiniteCounts got = envkit::count_nonfinite(part);
    EXPECT_EQ(got.nan, p.nan) << n;
    EXPECT_EQ(got.posinf, p.posinf) << n;
    EXPECT_EQ(got.neginf, p.neginf) << n;
  }
}

TEST_F(ImageIoTest, WritingNonFiniteValuesIsRefused) {
  Image img(2, 2, 3);
  img.pixels[4] = std::numeric_limits<float>::quiet_NaN();
  const std::string msg = error_of([&] { envkit::write_image(path("nan.exr"), img); });
  EXPECT_TRUE(starts_with(msg, path("nan.exr") + ": image has 1 non-finite values")) << msg;
  EXPECT_TRUE(listing().empty());
}

// ---- errors --------------------------------------------------------------------------------------------------

TEST_F(ImageIoTest, TruncatedExrNamesThePath) {
  Image img = test_image(256, 128, 3, 29);
  WriteOptions opt;
  opt.compression = "none";
  envkit::write_image(path("full.exr"), img, opt);
  std::ifstream in(path("full.exr"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  write_bytes(path("cut.exr"), bytes.substr(0, bytes.size() / 2));
  const std::string msg = error_of([&] { envkit::read_image(path("cut.exr")); });
  EXPECT_TRUE(starts_with(msg, path("cut.exr") + ": ")) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  EXPECT_NE(msg, "(no error)");
}

TEST_F(ImageIoTest, MissingUnknownAndCorruptFiles) {
  EXPECT_EQ(error_of([&] { envkit::read_image(path("absent.exr")); }), path("absent.exr") + ": no such file");
  write_bytes(path("notes.xyz"), "hello");
  const std::string unknown = error_of([&] { envkit::read_image(path("notes.xyz")); });
  EXPECT_TRUE(starts_with(unknown, path("notes.xyz") + ": unknown image format")) << unknown;
  write_bytes(path("junk.exr"), "this is not an exr file at all");
  const std::string corrupt = error_of([&] { envkit::read_image(path("junk.exr")); });
  EXPECT_TRUE(starts_with(corrupt, path("junk.exr") + ": cannot read")) << corrupt;
  EXPECT_EQ(corrupt.find('\n'), std::string::npos);
}

TEST_F(ImageIoTest, SevenChannelsAreRefused) {
  write_with_oiio(path("seven.exr"), 2, 2, {"R", "G", "B", "A", "Z", "U", "V"}, std::vector<float>(28, 0.5f));
  EXPECT_EQ(error_of([&] { envkit::read_image(path("seven.exr")); }),
            path("seven.exr") + ": unsupported channel count 7 (envkit reads 1 to 4 channels: Y, YA, RGB, RGBA)");
}

TEST_F(ImageIoTest, AbsurdHeaderSizeIsRefusedBeforeAllocating) {
  write_bytes(path("huge.pfm"), "PF\n1000000 1000000\n-1.0\n");
  const long before = max_rss_kb();
  const std::string msg = error_of([&] { envkit::read_image(path("huge.pfm")); });
  EXPECT_TRUE(starts_with(msg, path("huge.pfm") + ": image too large: 1000000x1000000")) << msg;
  EXPECT_LT(max_rss_kb() - before, 64 * 1024) << "no pixel memory may be allocated (peak RSS grew)";

  write_bytes(path("wide.pfm"), "PF\n40000 40000\n-1.0\n");  // sides fine, 1.6e9 texels too many
  const std::string texels = error_of([&] { envkit::read_image(path("wide.pfm")); });
  EXPECT_TRUE(starts_with(texels, path("wide.pfm") + ": image too large: 40000x40000 = 1600000000 texels")) << texels;

  ReadOptions small;
  small.max_side = 4;
  write_bytes(path("five.pgm"), std::string("P5\n5 1\n255\n") + std::string(5, '\x10'));
  EXPECT_THROW(envkit::read_image(path("five.pgm"), small), Error);
}

TEST_F(ImageIoTest, ZeroSizeImageIsAnError) {
  write_bytes(path("empty.pfm"), "PF\n0 0\n-1.0\n");
  const std::string msg = error_of([&] { envkit::read_image(path("empty.pfm")); });
  EXPECT_TRUE(starts_with(msg, path("empty.pfm") + ": ")) << msg;
  EXPECT_NE(msg, "(no error)");
  EXPECT_THROW(envkit::write_image(path("empty.exr"), Image()), Error);
}

TEST_F(ImageIoTest, WriteOptionMistakesAreErrors) {
  const Image img = test_image(4, 4, 3, 31);
  WriteOptions float_png;
  float_png.pixel_type = PixelType::Float;
  EXPECT_TRUE(starts_with(error_of([&] { envkit::write_image(path("f.png"), img, float_png); }), path("f.png") + ": "));
  WriteOptions half_tif;
  half_tif.pixel_type = PixelType::Half;
  EXPECT_THROW(envkit::write_image(path("h.tif"), img, half_tif), Error);
  EXPECT_TRUE(starts_with(error_of([&] { envkit::write_image(path("x.unknownext"), img); }),
                          path("x.unknownext") + ": unknown image format"));
  WriteOptions cube;
  cube.envmap_attribute = "cube";
  EXPECT_THROW(envkit::write_image(path("notcube.exr"), img, cube), Error) << "4x4 is not N x 6N";
  WriteOptions latlong_png;
  latlong_png.envmap_attribute = "latlong";
  EXPECT_THROW(envkit::write_image(path("ll.png"), img, latlong_png), Error);
  EXPECT_TRUE(listing().empty());
}

// ---- multi-part / MIP files -------------------------------------------------------------------------------

TEST_F(ImageIoTest, ReadsSubimageZeroOfMultiPartFiles) {
  const std::string file = path("parts.exr");
  // Parts share the display window; the second part's data window is a smaller crop.
  OIIO::ImageSpec specs[2] = {OIIO::ImageSpec(4, 2, 3, OIIO::TypeDesc::FLOAT),
                              OIIO::ImageSpec(2, 1, 3, OIIO::TypeDesc::FLOAT)};
  specs[1].full_width = 4;
  specs[1].full_height = 2;
  specs[0].attribute("oiio:subimagename", "first");
  specs[1].attribute("oiio:subimagename", "second");
  const std::vector<float> first(4 * 2 * 3, 1.5f), second(2 * 1 * 3, 7.0f);
  auto out = OIIO::ImageOutput::create(file);
  ASSERT_TRUE(out->open(file, 2, specs)) << out->geterror();
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, first.data()));
  ASSERT_TRUE(out->open(file, specs[1], OIIO::ImageOutput::AppendSubimage)) << out->geterror();
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, second.data()));
  out.reset();
  const Image img = envkit::read_image(file);
  EXPECT_EQ(img.width, 4);
  EXPECT_EQ(img.height, 2);
  for (float v : img.pixels) EXPECT_EQ(v, 1.5f);
}

TEST_F(ImageIoTest, LayeredExrChannelsComeInOiiosOrder) {
  // OpenEXR stores channels sorted by name, so a layer's colours come as diffuse.B, diffuse.G, diffuse.R: read in
  // that order they would swap red and blue. envkit must order them as OIIO does (R, G, B, A within each layer).
  const int w = 4, h = 2;
  for (const std::vector<std::string>& names :
       {std::vector<std::string>{"diffuse.R", "diffuse.G", "diffuse.B"},
        std::vector<std::string>{"beauty.red", "beauty.green", "beauty.blue", "beauty.alpha"},
        std::vector<std::string>{"R", "G", "B", "depth.Z"}, std::vector<std::string>{"a.b.Y", "a.b.A"}}) {
    std::vector<float> pixels(std::size_t(w) * h * names.size());
    for (std::size_t i = 0; i < pixels.size(); ++i) pixels[i] = 0.25f * float(i % names.size() + 1) + 0.01f * float(i);
    const std::string file = path("layered.exr");
    write_with_oiio(file, w, h, names, pixels);
    auto in = OIIO::ImageInput::open(file);
    ASSERT_TRUE(in) << OIIO::geterror();
    const OIIO::ImageSpec& spec = in->spec();
    std::vector<float> oiio(std::size_t(w) * h * spec.nchannels);
    ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, oiio.data()));
    const Image img = envkit::read_image(file);
    EXPECT_EQ(img.channel_names, spec.channelnames) << names[0];
    if (spec.alpha_channel >= 0) EXPECT_EQ(img.alpha_channel, spec.alpha_channel) << names[0];
    const std::vector<float> read(img.pixels.begin(), img.pixels.end());
    EXPECT_EQ(read, oiio) << names[0];
    EXPECT_EQ(read, pixels) << names[0] << ": written in OIIO's order, read back unchanged";
  }
}

TEST_F(ImageIoTest, LuminanceChromaExrIsReadAsRgb) {
  // What OpenEXR's RGBA interface writes to save space: Y at full resolution, RY and BY at half resolution in x and
  // y. exrenvmap reads such files; OIIO refuses them. A data window offset from the origin, alpha, a smooth image
  // (chroma subsampling loses only what varies from texel to texel).
  const int w = 64, h = 32;
  const Imath::Box2i display(Imath::V2i(0, 0), Imath::V2i(w - 1, h - 1));
  const Imath::Box2i data(Imath::V2i(4, 2), Imath::V2i(4 + w - 1, 2 + h - 1));  // multiples of the subsampling
  const auto colour = [&](int x, int y, int c) {
    const double s = double(x) / w, t = double(y) / h;
    return c == 0 ? 0.2 + 2.0 * s : c == 1 ? 0.5 + 0.8 * t * t : c == 2 ? 1.5 - s * t : 0.25 + 0.5 * s;
  };
  std::vector<Imf::Rgba> rgba(std::size_t(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      rgba[std::size_t(y) * w + x] =
          Imf::Rgba(float(colour(x, y, 0)), float(colour(x, y, 1)), float(colour(x, y, 2)), float(colour(x, y, 3)));
  const std::string file = path("yc.exr");
  {
    Imf::RgbaOutputFile out(file.c_str(), Imf::Header(display, data), Imf::WRITE_YCA);
    out.setFrameBuffer(rgba.data() - data.min.x - std::ptrdiff_t(data.min.y) * w, 1, w);
    out.writePixels(h);
  }
  {
    Imf::InputFile raw(file.c_str());  // the file really is luminance/chroma, subsampled
    const Imf::Channel* by = raw.header().channels().findChannel("BY");
    ASSERT_NE(by, nullptr);
    EXPECT_EQ(by->xSampling, 2);
    EXPECT_EQ(raw.header().channels().findChannel("R"), nullptr);
  }
  ReadReport report;
  const Image img = envkit::read_image(file, {}, &report);
  ASSERT_EQ(img.width, w);
  ASSERT_EQ(img.height, h);
  ASSERT_EQ(img.channels, 4);
  EXPECT_EQ(img.channel_names, (std::vector<std::string>{"R", "G", "B", "A"}));
  EXPECT_EQ(img.alpha_channel, 3);
  EXPECT_EQ(report.pixel_type, "half");
  // The texels OpenEXR's RGBA interface decodes, bit for bit, in envkit's channel order.
  std::vector<Imf::Rgba> decoded(rgba.size());
  {
    Imf::RgbaInputFile in(file.c_str());
    in.setFrameBuffer(decoded.data() - data.min.x - std::ptrdiff_t(data.min.y) * w, 1, w);
    in.readPixels(data.min.y, data.max.y);
  }
  double worst_colour = 0.0, worst_alpha = 0.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Imf::Rgba& d = decoded[std::size_t(y) * w + x];
      const float* px = img.at(x, y);
      ASSERT_EQ(px[0], float(d.r));
      ASSERT_EQ(px[1], float(d.g));
      ASSERT_EQ(px[2], float(d.b));
      ASSERT_EQ(px[3], float(d.a));
      // And close to what was written: the writer rounds luminance to 7 and chroma to 5 significand bits and
      // filters chroma to half resolution, so a dim channel beside bright ones comes back within a few percent of
      // the texel's brightest; alpha, stored whole, to half precision.
      const double brightest = std::max({colour(x, y, 0), colour(x, y, 1), colour(x, y, 2)});
      for (int c = 0; c < 3; ++c) worst_colour = std::max(worst_colour, std::abs(px[c] - colour(x, y, c)) / brightest);
      worst_alpha = std::max(worst_alpha, std::abs(px[3] - colour(x, y, 3)) / colour(x, y, 3));
    }
  EXPECT_LT(worst_colour, 0.04);
  EXPECT_LT(worst_alpha, 1e-3);
  // envinfo names the channels it shows; the file's Y, RY, BY never reach the user.
  const std::string info = run(std::string(ENVKIT_BIN_DIR) + "/envinfo '" + file + "' 2>&1");
  EXPECT_NE(info.find("channels (R, G, B, A)"), std::string::npos) << info;
}

TEST_F(ImageIoTest, OtherSubsampledChannelsAreOneClearError) {
  // R, G, B whole and a depth channel at half resolution: neither envkit nor OIIO reads it.
  const int w = 8, h = 4;
  Imf::Header header(w, h);
  header.channels().insert("R", Imf::Channel(Imf::FLOAT));
  header.channels().insert("G", Imf::Channel(Imf::FLOAT));
  header.channels().insert("B", Imf::Channel(Imf::FLOAT));
  header.channels().insert("Z", Imf::Channel(Imf::FLOAT, 2, 2));
  std::vector<float> rgb(std::size_t(w) * h * 3, 1.0f), z(std::size_t(w / 2) * (h / 2), 2.0f);
  Imf::FrameBuffer frame;
  for (int c = 0; c < 3; ++c)
    frame.insert(std::string(1, "RGB"[c]), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(rgb.data() + c),
                                                      3 * sizeof(float), 3 * sizeof(float) * w));
  frame.insert("Z",
               Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(z.data()), sizeof(float), sizeof(float) * (w / 2), 2, 2));
  const std::string file = path("z.exr");
  {
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(h);
  }
  const std::string message = error_of([&] { envkit::read_image(file); });
  EXPECT_TRUE(starts_with(message, file + ": ")) << message;
  EXPECT_NE(message.find("subsampled"), std::string::npos) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
}

// ---- metadata and the OpenEXR envmap attribute ---------------------------------------------------------------

TEST_F(ImageIoTest, MetadataIsCarriedSelectively) {
  Image img = test_image(8, 4, 3, 37);
  img.metadata["envkit:source"] = "probe.hdr";
  img.metadata["Copyright"] = "envkit tests";
  img.metadata["compression"] = "piz";       // structural key of some source file: not carried
  img.metadata["oiio:ColorSpace"] = "sRGB";  // would mislabel the output: not carried
  WriteOptions opt;
  opt.metadata["envkit:parameterization"] = "latlong";
  envkit::write_image(path("meta.exr"), img, opt);
  ReadReport report;
  const Image back = envkit::read_image(path("meta.exr"), {}, &report);
  EXPECT_EQ(back.metadata.at("envkit:parameterization"), "latlong");
  EXPECT_EQ(back.metadata.at("envkit:source"), "probe.hdr");
  EXPECT_EQ(back.metadata.at("Copyright"), "envkit tests");
  EXPECT_EQ(back.metadata.at("compression"), "zip");
  EXPECT_EQ(report.file_colorspace, "lin_rec709") << "not the stale sRGB tag";
  EXPECT_EQ(back.metadata.count("envmap"), 0u);
}

TEST_F(ImageIoTest, EnvmapAttributeIsTheTypedOpenExrAttribute) {
  const int n = 16;
  const Image cube = test_image(n, 6 * n, 3, 41, 0.1f, 2.0f);
  WriteOptions opt;
  opt.envmap_attribute = "cube";
  envkit::write_image(path("cube.exr"), cube, opt);
  const Image latlong = test_image(64, 32, 3, 43, 0.1f, 2.0f);
  opt.envmap_attribute = "latlong";
  envkit::write_image(path("latlong.exr"), latlong, opt);

  // OpenEXR sees an attribute of type envmap (not a string), and no competing "textureformat" string.
  for (const auto& [file, expected] :
       {std::pair{path("cube.exr"), Imf::ENVMAP_CUBE}, std::pair{path("latlong.exr"), Imf::ENVMAP_LATLONG}}) {
    Imf::InputFile in(file.c_str());
    const auto* envmap = in.header().findTypedAttribute<Imf::EnvmapAttribute>("envmap");
    ASSERT_NE(envmap, nullptr) << file;
    EXPECT_EQ(envmap->value(), expected) << file;
    EXPECT_EQ(in.header().find("textureformat"), in.header().end()) << file;
  }

  // Read back through envkit.
  EXPECT_EQ(envkit::read_image(path("cube.exr")).metadata.at("envmap"), "cube");
  const Image ll = envkit::read_image(path("latlong.exr"));
  EXPECT_EQ(ll.metadata.at("envmap"), "latlong");
  EXPECT_EQ(ll.pixels, latlong.pixels);

  // OpenEXR's own tools.
  // scripts/install-deps.sh installs Debian's openexr, which ships both tools.
  ASSERT_TRUE(fs::exists("/usr/bin/exrheader") && fs::exists("/usr/bin/exrenvmap")) << "OpenEXR tools missing";
  const std::string cube_header = run("/usr/bin/exrheader '" + path("cube.exr") + "'");
  EXPECT_NE(cube_header.find("envmap (type envmap): cube-face map"), std::string::npos) << cube_header;
  const std::string ll_header = run("/usr/bin/exrheader '" + path("latlong.exr") + "'");
  EXPECT_NE(ll_header.find("envmap (type envmap): latitude-longitude map"), std::string::npos) << ll_header;

  int code = -1;
  const std::string log =
      run("/usr/bin/exrenvmap -l -w 64 '" + path("cube.exr") + "' '" + path("from_cube.exr") + "' 2>&1", &code);
  EXPECT_EQ(code, 0) << log;
  EXPECT_NE(run("/usr/bin/exrheader '" + path("from_cube.exr") + "'").find("latitude-longitude map"),
            std::string::npos);
  const Image converted = envkit::read_image(path("from_cube.exr"));
  EXPECT_EQ(converted.width, 64);
  EXPECT_EQ(converted.height, 32);
  code = -1;
  run("/usr/bin/exrenvmap -c -w 8 '" + path("latlong.exr") + "' '" + path("from_ll.exr") + "' 2>&1", &code);
  EXPECT_EQ(code, 0);

  // A tiled, MIP-mapped file from exrenvmap: envkit reads MIP level 0.
  code = -1;
  run("/usr/bin/exrenvmap -m -l -w 64 '" + path("cube.exr") + "' '" + path("mip.exr") + "' 2>&1", &code);
  ASSERT_EQ(code, 0);
  const Image mip = envkit::read_image(path("mip.exr"));
  EXPECT_EQ(mip.width, 64);
  EXPECT_EQ(mip.height, 32);
  EXPECT_EQ(mip.metadata.at("envmap"), "latlong");
}

TEST_F(ImageIoTest, TypedEnvmapWinsOverAStaleTextureformatString) {
  // OIIO's own EXR writer stores a "textureformat" string next to the typed attribute; exrenvmap copies it
  // into its output, where it then contradicts the (converted) typed attribute.
  ASSERT_TRUE(fs::exists("/usr/bin/exrenvmap"))
      << "exrenvmap missing: scripts/install-deps.sh installs Debian's openexr";
  const int n = 8;
  write_with_oiio(path("oiio_cube.exr"), n, 6 * n, {"R", "G", "B"}, std::vector<float>(n * 6 * n * 3, 0.5f),
                  [](OIIO::ImageSpec& spec) { spec.attribute("textureformat", "CubeFace Environment"); });
  int code = -1;
  run("/usr/bin/exrenvmap -l -w 32 '" + path("oiio_cube.exr") + "' '" + path("ll.exr") + "' 2>&1", &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(envkit::read_image(path("ll.exr")).metadata.at("envmap"), "latlong");
}

// ---- atomic writes ---------------------------------------------------------------------------------------------

TEST_F(ImageIoTest, FailedWritesLeaveNeitherTargetNorTempFile) {
  // Make the writer fail half-way: a file-size limit turns large writes into EFBIG errors.
  const Image img = test_image(512, 256, 3, 47);
  const std::vector<std::string> targets = {path("big.exr"), path("big.pfm"), path("big.tif"), path("big.hdr")};
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
  auto* old_handler = ::signal(SIGXFSZ, SIG_IGN);
  rlimit limited = old;
  limited.rlim_cur = 64 * 1024;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limited), 0);
  std::vector<std::string> messages;
  for (const auto& target : targets) messages.push_back(error_of([&] { envkit::write_image(target, img); }));
  ::setrlimit(RLIMIT_FSIZE, &old);
  ::signal(SIGXFSZ, old_handler);
  for (std::size_t i = 0; i < targets.size(); ++i)
    EXPECT_TRUE(starts_with(messages[i], targets[i] + ": cannot write")) << messages[i];
  EXPECT_TRUE(listing().empty()) << "a temp file or partial target was left behind";
}

TEST_F(ImageIoTest, FailedOverwriteKeepsTheOldFile) {
  const Image old_img = test_image(8, 8, 3, 53);
  envkit::write_image(path("keep.exr"), old_img);
  Image bad = test_image(8, 8, 3, 59);
  bad.pixels[0] = std::numeric_limits<float>::infinity();
  EXPECT_THROW(envkit::write_image(path("keep.exr"), bad), Error);
  EXPECT_EQ(envkit::read_image(path("keep.exr")).pixels, old_img.pixels);
  EXPECT_EQ(listing(), std::vector<std::string>{"keep.exr"});
}

TEST_F(ImageIoTest, UnwritableDirectoryIsReported) {
  const Image img = test_image(4, 4, 3, 61);
  const std::string missing = path("nope/out.exr");
  const std::string msg = error_of([&] { envkit::write_image(missing, img); });
  EXPECT_TRUE(starts_with(msg, missing + ": directory '")) << msg;

  fs::create_directories(dir_ / "ro");
  fs::permissions(dir_ / "ro",
                  fs::perms::owner_read | fs::perms::owner_exec | fs::perms::others_read | fs::perms::others_exec);
  fs::permissions(dir_, fs::perms::others_read | fs::perms::others_exec, fs::perm_options::add);
  const std::string target = (dir_ / "ro" / "out.exr").string();
  // Root ignores permission bits: check as an unprivileged user in a child process.
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::geteuid() == 0 && (::setgid(65534) != 0 || ::setuid(65534) != 0)) ::_exit(90);
    const std::string m = error_of([&] { envkit::write_image(target, img); });
    ::_exit(m == target + ": cannot write: Permission denied" ? 0 : 1);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "expected \"" << target << ": cannot write: Permission denied\"";
  EXPECT_FALSE(fs::exists(target));
}

TEST_F(ImageIoTest, ReportSummaryIsOneLine) {
  envkit::write_image(path("s.exr"), test_image(4, 4, 3, 67));
  ReadReport report;
  envkit::read_image(path("s.exr"), {}, &report);
  const std::string s = report.summary();
  EXPECT_NE(s.find("openexr float"), std::string::npos) << s;
  EXPECT_NE(s.find("lin_rec709"), std::string::npos) << s;
  EXPECT_EQ(s.find('\n'), std::string::npos);
}

// The names envconvert checks before reading are the ones write_image accepts (one table in libenv).
TEST(ExrCompression, NamesAreRecognised) {
  for (const char* name : {"none", "zip", "ZIP", "piz", "dwaa:45", "b44a"})
    EXPECT_TRUE(envkit::is_exr_compression(name)) << name;
  for (const char* name : {"", "zap", "jpeg", ":45", "zip2"}) EXPECT_FALSE(envkit::is_exr_compression(name)) << name;
  EXPECT_NE(std::string(envkit::exr_compression_list()).find("dwab"), std::string::npos);
}
