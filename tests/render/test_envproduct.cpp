// envproduct on the command line: the figure and the EXR pictures exist with the sizes --help states, the product
// picture is BRDF x cos times the lighting texel-wise, each strategy's sample density converges to its pdf on a
// coarse grid, BSDF samples stay above an opaque surface, and bad input is refused with one line and no output.
#include <envkit/core/vec.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/latlong.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cli_support.h"

using namespace envkit;
namespace fs = std::filesystem;

namespace {

/// A smooth sky with a sun, on the pictures' own grid (so that the light table's texels are the pictures' texels).
const std::string kSunProbe = R"({"probe": "sun", "size": [128, 64], "elevation_deg": 35, "azimuth_deg": 20,
                                  "radius_deg": 4, "radiance": 200, "sky": 0.5})";
/// Strategies with low orders so the test stays quick (the options' own checks are envrender's).
const std::vector<std::string> kQuickOrders = {"--sh-order", "4", "--steerable-order", "4", "--threads", "2"};

class EnvProduct : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("envkit_envproduct_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  test::CommandResult envproduct(std::vector<std::string> args, bool quick_orders = true) {
    if (quick_orders) args.insert(args.end(), kQuickOrders.begin(), kQuickOrders.end());
    return test::run_tool("envproduct", args, dir_);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

/// Per cell of a cols x rows grid over a density picture (R: the samples' density, G: the pdf, per steradian), the
/// probability mass of each: sum over the cell's texels of value x texel solid angle.
struct CellMasses {
  std::vector<double> observed, expected;
};
CellMasses cell_masses(const Image& density, int cols, int rows) {
  const LatLongMap map(density.width, density.height);
  CellMasses m{std::vector<double>(std::size_t(cols * rows), 0.0), std::vector<double>(std::size_t(cols * rows), 0.0)};
  for (int y = 0; y < density.height; ++y)
    for (int x = 0; x < density.width; ++x) {
      const double omega = map.texel_solid_angle(x, y);
      const std::size_t cell = std::size_t((y * rows / density.height) * cols + x * cols / density.width);
      m.observed[cell] += density.at(x, y, 0) * omega;
      m.expected[cell] += density.at(x, y, 1) * omega;
    }
  return m;
}

}  // namespace

TEST_F(EnvProduct, WritesTheFigureAndThePicturesAtTheStatedSizes) {
  const std::vector<std::string> strategies = {"bsdf",      "light", "product", "product-wavelet", "product-steerable",
                                               "product-sh"};
  const auto r =
      envproduct({"--env", kSunProbe, "--width", "64", "-n", "64", "-o", path("figure.png"), "--exr", path("p"), "-q"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  // Three panels to a row (64 x 32 each, under a 22-texel label strip, 4 texels apart): the three pictures, then
  // the six default strategies in two rows.
  const Image figure = read_image(path("figure.png"));
  EXPECT_EQ(figure.width, 3 * 64 + 4 * 4);
  EXPECT_EQ(figure.height, 3 * (32 + 22) + 4 * 4);
  for (const char* part : {"brdf", "lighting", "product"}) {
    const Image picture = read_image(path(std::string("p.") + part + ".exr"));
    EXPECT_EQ(picture.width, 64) << part;
    EXPECT_EQ(picture.height, 32) << part;
  }
  for (const std::string& s : strategies) {
    ASSERT_TRUE(fs::exists(path("p.samples." + s + ".exr"))) << s;
    EXPECT_EQ(read_image(path("p.samples." + s + ".exr")).width, 64) << s;
  }
}

TEST_F(EnvProduct, TheProductIsBrdfCosTimesLightingTexelWise) {
  const auto r = envproduct({"--env", kSunProbe, "--material", R"({"type": "conductor", "roughness": 0.2})", "--normal",
                             "0.3,1,0", "--view", "0,1,-1", "--width", "128", "-n", "16", "--strategies", "bsdf", "-o",
                             path("figure.png"), "--exr", path("p"), "-q"});
  ASSERT_EQ(r.code, 0) << r.err;
  const Image brdf = read_image(path("p.brdf.exr")), lighting = read_image(path("p.lighting.exr")),
              product = read_image(path("p.product.exr"));
  ASSERT_EQ(product.width, brdf.width);
  double lobe = 0.0, lit = 0.0;
  for (int y = 0; y < product.height; ++y)
    for (int x = 0; x < product.width; ++x)
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(product.at(x, y, c), brdf.at(x, y, c) * lighting.at(x, y, c)) << x << "," << y << "," << c;
        lobe += brdf.at(x, y, c);
        lit += lighting.at(x, y, c);
      }
  EXPECT_GT(lobe, 0.0);  // neither factor is blank
  EXPECT_GT(lit, 0.0);
}

TEST_F(EnvProduct, EachStrategysSampleDensityConvergesToItsPdf) {
  const std::vector<std::string> strategies = {"bsdf",        "light",           "mis",        "product",
                                               "product-mis", "product-wavelet", "product-sh", "product-steerable-mis"};
  std::string list;
  for (const std::string& s : strategies) list += (list.empty() ? "" : ",") + s;
  const auto r =
      envproduct({"--env", kSunProbe, "--material", "rough030", "--normal", "0.2,1,0.1", "--width", "128", "-n",
                  "1000000", "--strategies", list, "-o", path("figure.png"), "--exr", path("p"), "-q"});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const std::string& s : strategies) {
    SCOPED_TRACE(s);
    const CellMasses m = cell_masses(read_image(path("p.samples." + s + ".exr")), 8, 4);
    double observed = 0.0, expected = 0.0;
    for (std::size_t c = 0; c < m.observed.size(); ++c) {
      observed += m.observed[c];
      expected += m.expected[c];
      // Cells with at least 1% of the draws: 10^4 samples or more, a few per mille of noise; the rest of the
      // bound is the pdf's midpoint rule over the texels.
      if (m.expected[c] > 0.01) {
        EXPECT_NEAR(m.observed[c] / m.expected[c], 1.0, 0.05) << "cell " << c;
      }
      if (m.expected[c] == 0.0) {
        EXPECT_EQ(m.observed[c], 0.0) << "cell " << c << ": samples where the pdf is 0";
      }
    }
    // Every draw lands somewhere: the density integrates to the pdf's integral (1, or less the BSDF draws lost
    // below the horizon, which neither counts).
    EXPECT_NEAR(observed, expected, 0.02);
    EXPECT_GT(expected, 0.5);
  }
}

TEST_F(EnvProduct, BsdfSamplesStayAboveAnOpaqueSurface) {
  const LatLongMap map(128, 64);
  for (const std::string& material : {std::string("rough050"), std::string("matte"), std::string("rough005")}) {
    SCOPED_TRACE(material);
    const std::string normal = "1,1,0";
    const auto r =
        envproduct({"--env",   kSunProbe, "--material", material, "--normal",     normal, "--view", "0,0.2,-1",
                    "--width", "128",     "-n",         "100000", "--strategies", "bsdf", "-o",     path("figure.png"),
                    "--exr",   path("p"), "-f",         "-q"});
    ASSERT_EQ(r.code, 0) << r.err;
    const Image density = read_image(path("p.samples.bsdf.exr"));
    const Vec3 n = Vec3(1, 1, 0) / std::sqrt(2.0);
    double above = 0.0;
    for (int y = 0; y < density.height; ++y)
      for (int x = 0; x < density.width; ++x) {
        Vec3 d;
        map.to_direction(Vec2(x + 0.5, y + 0.5), d);
        // Texels wholly below the surface (their centre more than half a texel's diagonal under the horizon).
        if ((d ^ n) < -0.05) {
          EXPECT_EQ(density.at(x, y, 0), 0.0f) << x << "," << y;
        }
        if ((d ^ n) > 0.0) above += density.at(x, y, 0) * map.texel_solid_angle(x, y);
      }
    EXPECT_GT(above, 0.5);
  }
}

TEST_F(EnvProduct, TheSeedsCaseAMeasuredMaterialUnderAProbe) {
  // A MERL-format file of a Lambertian BRDF of albedo 0.5 (every cell f = 0.5 / pi, over the format's channel scales):
  // the measured material must picture and sample as the analytic diffuse one.
  {
    std::ofstream out(path("lambert.binary"), std::ios::binary);
    const std::int32_t dims[3] = {90, 90, 180};
    out.write(reinterpret_cast<const char*>(dims), sizeof dims);
    const double scale[3] = {1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0};
    for (double s : scale) {
      const std::vector<double> values(std::size_t(90) * 90 * 180, 0.5 / kPi / s);
      out.write(reinterpret_cast<const char*>(values.data()), std::streamsize(values.size() * sizeof(double)));
    }
  }
  const std::string measured = R"({"type": "measured", "file": ")" + path("lambert.binary") + R"("})";
  for (const auto& [material, prefix] :
       {std::pair{measured, std::string("m")},
        std::pair{std::string(R"({"type": "diffuse", "albedo": 0.5})"), std::string("d")}}) {
    const auto r =
        envproduct({"--env", kSunProbe, "--material", material, "--normal", "0,1,0.3", "--width", "128", "-n", "200000",
                    "--strategies", "bsdf,product", "-o", path(prefix + ".png"), "--exr", path(prefix), "-q"});
    ASSERT_EQ(r.code, 0) << r.err;
  }
  const Image m = read_image(path("m.brdf.exr")), d = read_image(path("d.brdf.exr"));
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(m.at(x, y, c), d.at(x, y, c), 1e-4 + 1e-3 * d.at(x, y, c)) << x << "," << y;
  for (const char* s : {"bsdf", "product"}) {
    SCOPED_TRACE(s);
    const CellMasses masses = cell_masses(read_image(path(std::string("m.samples.") + s + ".exr")), 8, 4);
    for (std::size_t c = 0; c < masses.observed.size(); ++c)
      if (masses.expected[c] > 0.02) {
        EXPECT_NEAR(masses.observed[c] / masses.expected[c], 1.0, 0.05) << "cell " << c;
      }
  }
}

TEST_F(EnvProduct, BadInputGetsOneLineAndNoOutput) {
  struct Case {
    std::vector<std::string> args;
    int code;
    std::string starts;
  };
  const std::vector<Case> cases = {
      {{"--material", "gold"}, 1, "envproduct: --material: 'gold' is neither JSON, a preset ("},
      {{"--material", R"({"type": "conductor", "roughness": 2})"},
       1,
       "envproduct: --material:1: material.roughness: must be in (0, 1]"},
      {{"--env", path("missing.exr")}, 1, "envproduct: --env:1: environment.image: "},
      {{"--strategies", "product-sh", "--sh-order", "40"}, 1, "envproduct: --sh-order 40: must be in 1..16"},
      {{"--strategies", "product-wavelet", "--wavelet-resolution", "48"},
       1,
       "envproduct: --wavelet-resolution 48: must be a power of two in 2..256"},
      {{"--view", "0,-1,0"}, 2, "--view: points below the surface"},
      {{"--normal", "1,2"}, 2, "--normal: expected x,y,z"},
      {{"--strategies", "bsdf,best"}, 2, "--strategies: unknown strategy 'best'"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args[0] + " " + c.args[1]);
    std::vector<std::string> args = c.args;
    args.insert(args.end(), {"--width", "32", "-n", "4", "-o", path("figure.png"), "--exr", path("p"), "-q"});
    const auto r = envproduct(args, false);
    EXPECT_EQ(r.code, c.code) << r.err;
    ASSERT_FALSE(r.err_lines().empty());
    EXPECT_EQ(r.err_lines()[0].rfind(c.starts, 0), 0u) << r.err;
    if (c.code == 1) {
      EXPECT_EQ(r.err_lines().size(), 1u) << r.err;
    }
    EXPECT_FALSE(fs::exists(path("figure.png")));
    EXPECT_FALSE(fs::exists(path("p.brdf.exr")));
  }
}
