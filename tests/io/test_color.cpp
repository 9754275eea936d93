// Tests for color.h and the shipped OCIO config. Expected values come from the published formulas and
// matrices (IEC 61966-2-1 sRGB, ITU-R BT.709, ACES AP0/AP1 with Bradford D60->D65), not from envkit.
#include <OpenColorIO/OpenColorIO.h>
#include <envkit/core/error.h>
#include <envkit/core/image.h>
#include <envkit/io/color.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <string>

namespace fs = std::filesystem;
using envkit::Error;
using envkit::Image;

namespace {

const std::string kShippedConfig = std::string(ENVKIT_SOURCE_DIR) + "/libenv/data/ocio/config.ocio";

double srgb_eotf(double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); }
double srgb_oetf(double l) { return l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1.0 / 2.4) - 0.055; }
double rec709_inverse_oetf(double v) { return v < 0.081 ? v / 4.5 : std::pow((v + 0.099) / 1.099, 1.0 / 0.45); }

Image rgb(float r, float g, float b) {
  Image img(1, 1, 3);
  img.pixels = {r, g, b};
  return img;
}

/// Sets (or unsets, for nullopt) an environment variable for the scope, restoring it afterwards.
class EnvGuard {
 public:
  EnvGuard(const char* name, std::optional<std::string> value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value)
      ::setenv(name, value->c_str(), 1);
    else
      ::unsetenv(name);
  }
  ~EnvGuard() {
    if (old_)
      ::setenv(name_, old_->c_str(), 1);
    else
      ::unsetenv(name_);
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

/// The tests describe the shipped config: make sure a developer's $OCIO does not leak in.
class ColorTest : public ::testing::Test {
 protected:
  EnvGuard ocio_{"OCIO", std::nullopt};
  EnvGuard own_{"ENVKIT_OCIO_CONFIG", std::nullopt};
};

}  // namespace

TEST_F(ColorTest, ShippedConfigIsValid) {
  namespace OCIO = OCIO_NAMESPACE;
  auto config = OCIO::Config::CreateFromFile(kShippedConfig.c_str());
  EXPECT_NO_THROW(config->validate());
  EXPECT_EQ(envkit::working_space(), "lin_rec709");
  const auto names = envkit::colorspace_names();
  for (const char* n : {"lin_rec709", "srgb", "rec709", "acescg", "aces2065-1", "lin_p3d65", "raw"})
    EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
  EXPECT_TRUE(envkit::is_data_colorspace("raw"));
  EXPECT_FALSE(envkit::is_data_colorspace("srgb"));
}

TEST_F(ColorTest, NamesResolveThroughAliasesRolesAndCase) {
  EXPECT_EQ(envkit::canonical_colorspace("scene_linear"), "lin_rec709");
  EXPECT_EQ(envkit::canonical_colorspace("ACEScg"), "acescg");
  EXPECT_EQ(envkit::canonical_colorspace("sRGB"), "srgb");
  EXPECT_EQ(envkit::canonical_colorspace("sRGB - Texture"), "srgb");
  EXPECT_EQ(envkit::canonical_colorspace("data"), "raw");
}

TEST_F(ColorTest, UnknownColorSpaceListsValidNamesOnOneLine) {
  Image img = rgb(0.5f, 0.5f, 0.5f);
  try {
    envkit::convert_colorspace(img, "no-such-space", "lin_rec709");
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("'no-such-space'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("lin_rec709"), std::string::npos) << msg;
    EXPECT_NE(msg.find("acescg"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

TEST_F(ColorTest, Srgb128DecodesToTheSrgbEotf) {
  Image img = rgb(128.0f / 255.0f, 128.0f / 255.0f, 128.0f / 255.0f);
  envkit::convert_colorspace(img, "srgb");
  for (float v : img.pixels) EXPECT_NEAR(v, 0.2158605, 1e-4);
  EXPECT_NEAR(srgb_eotf(128.0 / 255.0), 0.2158605, 1e-6) << "the reference formula itself";
}

TEST_F(ColorTest, SrgbMatchesThePiecewiseFormulaEverywhere) {
  Image img(256, 1, 3);
  for (int i = 0; i < 256; ++i)
    for (int c = 0; c < 3; ++c) img.at(i, 0, c) = static_cast<float>(i) / 255.0f;
  envkit::convert_colorspace(img, "srgb", "lin_rec709");
  for (int i = 0; i < 256; ++i) {
    const double expected = srgb_eotf(i / 255.0);
    EXPECT_NEAR(img.at(i, 0, 1), expected, 1e-5 + 1e-4 * expected) << "code value " << i;
  }
  envkit::convert_colorspace(img, "lin_rec709", "srgb");
  for (int i = 0; i < 256; ++i) EXPECT_NEAR(img.at(i, 0, 0), i / 255.0, 2e-5) << "round trip at " << i;
}

TEST_F(ColorTest, Rec709IsTheInverseCameraOetf) {
  Image img = rgb(0.5f, 0.05f, 1.0f);
  envkit::convert_colorspace(img, "rec709");
  EXPECT_NEAR(img.pixels[0], rec709_inverse_oetf(0.5), 1e-4);
  // OCIO's ExponentWithLinearTransform derives the toe from slope continuity (slope ~4.49, break ~0.0181)
  // instead of BT.709's rounded 4.5 / 0.018: within 0.4% there, exact on the power segment.
  EXPECT_NEAR(img.pixels[1], rec709_inverse_oetf(0.05), 0.004 * rec709_inverse_oetf(0.05));
  EXPECT_NEAR(img.pixels[2], 1.0, 1e-4);
}

TEST_F(ColorTest, AcescgToRec709MatchesThePublishedMatrix) {
  // AP1 -> linear Rec.709 (Bradford D60 -> D65), columns of the matrix.
  const double m[3][3] = {{1.70505, -0.62179, -0.08326}, {-0.13026, 1.14080, -0.01055}, {-0.02400, -0.12897, 1.15297}};
  for (int col = 0; col < 3; ++col) {
    Image img = rgb(col == 0, col == 1, col == 2);
    envkit::convert_colorspace(img, "acescg", "lin_rec709");
    for (int row = 0; row < 3; ++row) EXPECT_NEAR(img.pixels[row], m[row][col], 1e-3) << row << "," << col;
  }
}

TEST_F(ColorTest, Aces2065ToAcescgMatchesThePublishedMatrix) {
  Image img = rgb(1, 0, 0);
  envkit::convert_colorspace(img, "aces2065-1", "acescg");
  EXPECT_NEAR(img.pixels[0], 1.4514393, 1e-4);
  EXPECT_NEAR(img.pixels[1], -0.0765538, 1e-4);
  EXPECT_NEAR(img.pixels[2], 0.0083161, 1e-4);
}

TEST_F(ColorTest, P3D65ToRec709MatchesThePrimaries) {
  Image img = rgb(1, 0, 0);
  envkit::convert_colorspace(img, "lin_p3d65", "lin_rec709");
  EXPECT_NEAR(img.pixels[0], 1.2249, 1e-3);
  EXPECT_NEAR(img.pixels[1], -0.0421, 1e-3);
  EXPECT_NEAR(img.pixels[2], -0.0196, 1e-3);
  Image white = rgb(1, 1, 1);
  envkit::convert_colorspace(white, "lin_p3d65", "lin_rec709");
  for (float v : white.pixels) EXPECT_NEAR(v, 1.0, 1e-4) << "same D65 white";
}

TEST_F(ColorTest, AlphaIsLeftAloneAndGreyStaysGrey) {
  Image rgba(2, 1, 4);
  rgba.pixels = {1, 0, 0, 0.25f, 0.5f, 0.5f, 0.5f, 0.75f};
  envkit::convert_colorspace(rgba, "acescg", "lin_rec709");
  EXPECT_EQ(rgba.pixels[3], 0.25f);
  EXPECT_EQ(rgba.pixels[7], 0.75f);
  EXPECT_NEAR(rgba.pixels[0], 1.70505, 1e-3);

  Image ya(1, 1, 2);
  ya.pixels = {128.0f / 255.0f, 0.5f};
  envkit::convert_colorspace(ya, "srgb");
  EXPECT_NEAR(ya.pixels[0], 0.2158605, 1e-4);
  EXPECT_EQ(ya.pixels[1], 0.5f);
}

TEST_F(ColorTest, LargeImagesConvertLikeSinglePixels) {
  // The parallel, row-blocked path must agree with converting each pixel alone.
  Image big(701, 333, 4);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 4.0f);
  for (float& v : big.pixels) v = u(rng);
  Image copy = big;
  envkit::convert_colorspace(big, "acescg");
  for (int k = 0; k < 50; ++k) {
    const int x = static_cast<int>(rng() % 701), y = static_cast<int>(rng() % 333);
    Image one = rgb(copy.at(x, y, 0), copy.at(x, y, 1), copy.at(x, y, 2));
    envkit::convert_colorspace(one, "acescg");
    for (int c = 0; c < 3; ++c) EXPECT_FLOAT_EQ(big.at(x, y, c), one.pixels[c]);
    EXPECT_EQ(big.at(x, y, 3), copy.at(x, y, 3));
  }
}

TEST_F(ColorTest, OverflowDoesNotProduceNonFiniteValues) {
  Image img = rgb(3.0e38f, -3.0e38f, 3.0e38f);
  envkit::convert_colorspace(img, "acescg");
  for (float v : img.pixels) EXPECT_TRUE(std::isfinite(v)) << v;
}

TEST_F(ColorTest, LuminanceWeights) {
  const envkit::Vec3 w = envkit::luminance_weights(envkit::working_space());
  EXPECT_NEAR(w.x, 0.2126, 1e-6);
  EXPECT_NEAR(w.y, 0.7152, 1e-6);
  EXPECT_NEAR(w.z, 0.0722, 1e-6);
  // AP1: Y row of its RGB->XYZ is (0.2722, 0.6741, 0.0537) at the ACES white; seen from D65 after
  // Bradford adaptation it moves slightly, but white must keep luminance 1.
  const envkit::Vec3 a = envkit::luminance_weights("acescg");
  EXPECT_NEAR(a.x + a.y + a.z, 1.0, 1e-4);
  EXPECT_NEAR(a.x, 0.2722, 0.01);
  EXPECT_NEAR(a.y, 0.6741, 0.01);
  EXPECT_NEAR(a.z, 0.0537, 0.01);
  EXPECT_THROW(envkit::luminance_weights("raw"), Error);
}

TEST_F(ColorTest, DisplayEncodingStandardAndTonemapped) {
  Image img(3, 1, 3);
  img.pixels = {0.18f, 0.18f, 0.18f, 4.0f, 4.0f, 4.0f, 0.0f, 0.0f, 0.0f};
  Image tonemapped = img;
  envkit::encode_for_display(img, "sRGB", "Standard");
  EXPECT_NEAR(img.pixels[0], srgb_oetf(0.18), 1e-4);
  EXPECT_EQ(img.pixels[3], 1.0f) << "clipped at display white";
  EXPECT_NEAR(img.pixels[6], 0.0, 1e-6);

  envkit::encode_for_display(tonemapped, "sRGB", "ACES 1.0 - SDR Video");
  for (float v : tonemapped.pixels) EXPECT_TRUE(v >= 0.0f && v <= 1.0f) << v;
  EXPECT_LT(tonemapped.pixels[0], tonemapped.pixels[3]) << "monotonic";
  EXPECT_LT(tonemapped.pixels[3], 1.0f) << "4.0 is not clipped by the tone curve";

  try {
    envkit::encode_for_display(img, "sRGB", "Nope");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("Standard"), std::string::npos) << e.what();
  }
  EXPECT_THROW(envkit::encode_for_display(img, "NoDisplay", "Standard"), Error);
}

TEST_F(ColorTest, GammaDecode) {
  Image img = rgb(0.5f, 0.0f, 1.0f);
  envkit::decode_gamma(img, 2.2);
  EXPECT_NEAR(img.pixels[0], std::pow(0.5, 2.2), 1e-5);
  EXPECT_NEAR(img.pixels[1], 0.0, 1e-7);
  EXPECT_NEAR(img.pixels[2], 1.0, 1e-6);
  EXPECT_THROW(envkit::decode_gamma(img, -1.0), Error);
}

TEST(ColorConfigSelection, OcioVariableIsHonouredAndBrokenConfigsAreReported) {
  const fs::path dir = fs::temp_directory_path() / ("envkit_color_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  EnvGuard own("ENVKIT_OCIO_CONFIG", std::nullopt);
  {
    // A user config that only knows two spaces.
    const std::string user = (dir / "user.ocio").string();
    std::ofstream(user) << "ocio_profile_version: 2\n"
                           "roles: {scene_linear: my_linear, default: my_linear}\n"
                           "file_rules:\n  - !<Rule> {name: Default, colorspace: my_linear}\n"
                           "displays: {d: [!<View> {name: v, colorspace: my_linear}]}\n"
                           "colorspaces:\n"
                           "  - !<ColorSpace> {name: my_linear}\n"
                           "  - !<ColorSpace> {name: my_log, to_scene_reference: !<LogTransform> {base: 2}}\n";
    EnvGuard ocio("OCIO", user);
    EXPECT_EQ(envkit::working_space(), "my_linear");
    EXPECT_EQ(envkit::color_config_source(), "$OCIO=" + user);
    const auto names = envkit::colorspace_names();
    EXPECT_EQ(names, (std::vector<std::string>{"my_linear", "my_log"}));
    EXPECT_THROW(envkit::canonical_colorspace("acescg"), Error) << "not in this config";
  }
  {
    const std::string broken = (dir / "broken.ocio").string();
    std::ofstream(broken) << "this is: [not an OCIO config\n";
    EnvGuard ocio("OCIO", broken);
    try {
      envkit::working_space();
      FAIL() << "a broken $OCIO must be reported";
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind("$OCIO=" + broken + ": ", 0), 0u) << msg;
      EXPECT_NE(msg.find("unset OCIO"), std::string::npos) << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
  }
  {
    EnvGuard ocio("OCIO", std::nullopt);
    EXPECT_EQ(envkit::working_space(), "lin_rec709") << "back to the shipped config";
    const std::string source = envkit::color_config_source();
    EXPECT_EQ(source.substr(source.size() - std::string("ocio/config.ocio").size()), "ocio/config.ocio");
    // ENVKIT_OCIO_CONFIG overrides the shipped config's location.
    EnvGuard own2("ENVKIT_OCIO_CONFIG", (dir / "user.ocio").string());
    EXPECT_EQ(envkit::working_space(), "my_linear");
  }
  fs::remove_all(dir);
}

// color.cpp answers the questions of every float read and write from a table of the shipped config, without loading
// OpenColorIO; naming the same file through ENVKIT_OCIO_CONFIG makes OpenColorIO answer. Both must agree, row by row.
TEST_F(ColorTest, ShippedTableAnswersAsOpenColorIODoes) {
  const std::vector<std::string> rows = {"lin_rec709", "scene_linear", "srgb", "rec709", "raw", "data"};
  struct Answers {
    std::string working;
    std::vector<std::string> canonical;
    std::vector<bool> data;
    envkit::Vec3 luma;
  };
  const auto ask = [&rows] {
    Answers a{envkit::working_space(), {}, {}, envkit::luminance_weights("scene_linear")};
    for (const std::string& name : rows) {
      a.canonical.push_back(envkit::canonical_colorspace(name));
      a.data.push_back(envkit::is_data_colorspace(name));
    }
    return a;
  };
  const Answers table = ask();
  Answers ocio;
  {
    EnvGuard own("ENVKIT_OCIO_CONFIG", kShippedConfig);
    ocio = ask();
  }
  EXPECT_EQ(table.working, ocio.working);
  EXPECT_EQ(table.canonical, ocio.canonical);
  EXPECT_EQ(table.data, ocio.data);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(table.luma[k], ocio.luma[k]) << k;
  EXPECT_EQ(envkit::luminance_weights("lin_rec709"), table.luma);

  // Converting between two of the table's names for one space leaves the pixels alone; between two spaces it
  // converts (through OpenColorIO).
  Image same = rgb(0.5f, 0.25f, 2.0f);
  envkit::convert_colorspace(same, "scene_linear", "lin_rec709");
  EXPECT_EQ(same.pixels[0], 0.5f);
  EXPECT_EQ(same.pixels[1], 0.25f);
  EXPECT_EQ(same.pixels[2], 2.0f);
  Image encoded = rgb(0.5f, 0.5f, 0.5f);
  envkit::convert_colorspace(encoded, "lin_rec709", "srgb");
  EXPECT_NEAR(encoded.pixels[0], srgb_oetf(0.5), 1e-5);
}
