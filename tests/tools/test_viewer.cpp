// The three.js viewer (web/) in Debian's headless Chromium against envkit's own split-sum shading.
// envprobe makes a sky, envprefilter its GGX chain (KTX2, RGBA16F) and DFG LUT (EXR); tests/js/viewer_capture.mjs
// serves web/ and those files on 127.0.0.1, opens the page with a fixed camera, and saves the canvas. Every pixel is
// then shaded here by SplitSumIbl (split_sum.h) from the same files, through the page's display transform
// (exposure, Reinhard, sRGB, 8 bits), and compared: per sphere and for the background, the median absolute
// difference over the pixels and colour channels must be <= 1 of 255 and at most 1% of them may differ by more than
// 8 of 255 (measured with SwiftShader: medians 0.25 to 0.42, 0.01% above 8). A copy of the page whose shader reads the
// LUT's A and B the wrong way round must fail the same comparison (medians 17 to 21), so the comparison is known to
// see a wrong split-sum; so do a roughness-squared mip selection (2.7 to 10.6 on the middle spheres), LUT rows
// upside down and three's x flip of cube lookups (tried by hand, not kept).
#include <envkit/ibl/ktx2.h>
#include <envkit/ibl/split_sum.h>
#include <envkit/io/image_io.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_support.h"

using namespace envkit;
namespace fs = std::filesystem;

namespace {

constexpr double kMedianTolerance = 1.0;  // 8-bit levels
constexpr double kOutlierLevels = 8.0;    // 8-bit levels
constexpr double kOutlierFraction = 0.01;

// The scene the test asks the page for (URL parameters), and the geometry web/viewer.js builds from them.
constexpr int kWidth = 640, kHeight = 160;
const std::vector<double> kRoughness = {0.0, 0.2, 0.45, 0.7, 1.0};
const Vec3 kF0(0.9, 0.6, 0.3);
constexpr double kExposure = 0.5, kFovDeg = 20.0, kCameraZ = 10.0, kSpacing = 2.5;

std::string find_chromium() {
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (fs::exists(p)) return p;
  return "";
}

std::string join(const std::vector<double>& v) {
  std::ostringstream s;
  for (std::size_t i = 0; i < v.size(); ++i) s << (i ? "," : "") << v[i];
  return s.str();
}

// The page's display transform (web/shaders.js), in 8-bit units.
double display(double radiance) {
  double x = kExposure * std::max(radiance, 0.0);
  x = x / (1.0 + x);
  x = x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
  return 255.0 * x;
}

struct Group {
  std::vector<double> diffs;  // |captured - reference| per pixel and channel, 8-bit levels
  double median() {
    if (diffs.empty()) return 0.0;
    std::nth_element(diffs.begin(), diffs.begin() + diffs.size() / 2, diffs.end());
    return diffs[diffs.size() / 2];
  }
  double outliers() const {
    return diffs.empty()
               ? 0.0
               : double(std::count_if(diffs.begin(), diffs.end(), [](double d) { return d > kOutlierLevels; })) /
                     double(diffs.size());
  }
};

class Viewer : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("envkit_viewer_" + std::to_string(::getpid()));
    fs::create_directories(dir_ / "data");
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs the capture script on `web_root`; returns the RGBA8 pixels (rows top to bottom).
  std::vector<unsigned char> capture(const std::string& chromium, const fs::path& web_root, const std::string& name) {
    const std::string query = "map=data/sky_ggx.ktx2&lut=data/dfg.exr&static=1&size=" + std::to_string(kWidth) + "x" +
                              std::to_string(kHeight) + "&roughness=" + join(kRoughness) +
                              "&f0=" + join({kF0.x, kF0.y, kF0.z}) + "&exposure=" + join({kExposure}) +
                              "&fov=" + join({kFovDeg}) + "&camera=0,0," + join({kCameraZ});
    const std::string script = std::string(ENVKIT_SOURCE_DIR) + "/tests/js/viewer_capture.mjs";
    const fs::path prefix = dir_ / name;
    const test::CommandResult r = test::run_command(
        "node", {script, chromium, (dir_ / "data").string(), query, prefix.string(), web_root.string()}, dir_);
    EXPECT_EQ(r.code, 0) << r.err;
    const nlohmann::json size = nlohmann::json::parse(test::read_text(prefix.string() + ".json"));
    EXPECT_EQ(size["width"], kWidth);
    EXPECT_EQ(size["height"], kHeight);
    const std::string bytes = test::read_text(prefix.string() + ".rgba");
    EXPECT_EQ(bytes.size(), std::size_t(kWidth) * kHeight * 4);
    return {bytes.begin(), bytes.end()};
  }

  // Compares captured pixels with SplitSumIbl's shading of the same scene: one group per sphere, then the background.
  std::vector<Group> compare(const std::vector<unsigned char>& rgba, const SplitSumIbl& ibl) {
    const int n = int(kRoughness.size());
    std::vector<Group> groups(n + 1);
    const double t = std::tan(kFovDeg * M_PI / 360.0), aspect = double(kWidth) / kHeight;
    const Vec3 eye(0, 0, kCameraZ);
    const double pixel = 2.0 * kCameraZ * t / kHeight;  // world size of a pixel at the spheres' distance
    for (int j = 0; j < kHeight; ++j)
      for (int i = 0; i < kWidth; ++i) {
        const double x = 2.0 * (i + 0.5) / kWidth - 1.0, y = 1.0 - 2.0 * (j + 0.5) / kHeight;
        const Vec3 d = Vec3(x * aspect * t, y * t, -1.0).normalized();
        int hit = -1;
        double hit_t = 1e30;
        bool near_rim = false;
        for (int k = 0; k < n; ++k) {
          const Vec3 c((k - (n - 1) / 2.0) * kSpacing, 0, 0);
          const Vec3 oc = c - eye;
          const double along = oc ^ d, miss = std::sqrt(std::max(0.0, (oc ^ oc) - along * along));
          // Rasterised tessellation and the exact sphere disagree on the outline: leave 2 pixels around it out.
          if (std::abs(miss - 1.0) < 2.0 * pixel) near_rim = true;
          if (miss < 1.0) {
            const double th = along - std::sqrt(1.0 - miss * miss);
            if (th < hit_t) hit_t = th, hit = k;
          }
        }
        if (near_rim) continue;
        Vec3 want;
        if (hit >= 0) {
          const Vec3 c((hit - (n - 1) / 2.0) * kSpacing, 0, 0);
          const Vec3 nrm = (eye + hit_t * d - c).normalized();
          want = ibl.specular(nrm, -d, kRoughness[hit], kF0);
        } else {
          want = ibl.radiance(d, 0.0);
        }
        Group& g = groups[hit >= 0 ? hit : n];
        const unsigned char* got = &rgba[(std::size_t(j) * kWidth + i) * 4];
        for (int ch = 0; ch < 3; ++ch) g.diffs.push_back(std::abs(got[ch] - display(want[ch])));
      }
    return groups;
  }

  fs::path dir_;
};

TEST_F(Viewer, SpheresMatchEnvkitSplitSum) {
  const std::string chromium = find_chromium();
  // scripts/install-deps.sh installs chromium for the README's test command: its absence is a broken set-up, not a
  // skip.
  ASSERT_FALSE(chromium.empty()) << "Debian's chromium is not installed (scripts/install-deps.sh installs it)";
  const fs::path web = fs::path(ENVKIT_SOURCE_DIR) / "web";
  ASSERT_TRUE(fs::exists(web / "node_modules/three/build/three.module.js"))
      << "three is not installed in web/: run scripts/install-deps.sh (npm ci in web/)";

  const fs::path data = dir_ / "data";
  test::CommandResult r =
      test::run_tool("envprobe", {"default", "-o", (dir_ / "sky.exr").string(), "--size", "256x128"}, dir_);
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_tool("envprefilter",
                     {(dir_ / "sky.exr").string(), "-o", (data / "sky_ggx.ktx2").string(), "--size", "64", "--lut",
                      (data / "dfg.exr").string(), "--lut-size", "64", "-q"},
                     dir_);
  ASSERT_EQ(r.code, 0) << r.err;

  Ktx2Texels chain = read_ktx2((data / "sky_ggx.ktx2").string());
  std::vector<double> roughness;
  std::stringstream list(chain.key_values.at("envkit:ibl_roughness"));
  for (std::string item; std::getline(list, item, ',');) roughness.push_back(std::stod(item));
  const SplitSumIbl ibl(std::move(chain.levels), roughness, read_image((data / "dfg.exr").string()));

  const std::vector<unsigned char> rgba = capture(chromium, web, "viewer");
  ASSERT_EQ(rgba.size(), std::size_t(kWidth) * kHeight * 4);
  std::vector<Group> groups = compare(rgba, ibl);
  for (std::size_t k = 0; k < groups.size(); ++k) {
    const std::string what =
        k < kRoughness.size() ? "sphere of roughness " + std::to_string(kRoughness[k]) : std::string("background");
    ASSERT_GT(groups[k].diffs.size(), 300u) << what;
    std::printf("%s: %zu values, median |difference| %.2f of 255, %.2f%% above %.0f\n", what.c_str(),
                groups[k].diffs.size(), groups[k].median(), 100.0 * groups[k].outliers(), kOutlierLevels);
    EXPECT_LE(groups[k].median(), kMedianTolerance) << what;
    EXPECT_LE(groups[k].outliers(), kOutlierFraction) << what;
  }

  // The same page with A and B of the LUT swapped must fail the comparison on the rough spheres.
  const fs::path broken = dir_ / "web_swapped_lut";
  fs::create_directories(broken);
  for (const char* f : {"index.html", "viewer.js", "ibl.js"}) fs::copy_file(web / f, broken / f);
  fs::create_directory_symlink(web / "node_modules", broken / "node_modules");
  std::string shaders = test::read_text(web / "shaders.js");
  const std::string lookup = ".rg;  // ENVKIT_LUT_LOOKUP";
  const std::size_t at = shaders.find(lookup);
  ASSERT_NE(at, std::string::npos) << "web/shaders.js no longer marks its LUT lookup";
  shaders.replace(at, 3, ".gr");
  std::ofstream(broken / "shaders.js") << shaders;
  std::vector<Group> wrong = compare(capture(chromium, broken, "swapped"), ibl);
  int failing = 0;
  for (std::size_t k = 0; k < kRoughness.size(); ++k) {
    failing += wrong[k].median() > kMedianTolerance;
    std::printf("swapped LUT, sphere %zu: median |difference| %.2f of 255\n", k, wrong[k].median());
  }
  EXPECT_GE(failing, 3) << "a viewer with A and B swapped passes the comparison";
}

}  // namespace
