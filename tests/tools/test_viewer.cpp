// The three.js viewer (web/) in Debian's headless Chromium against envkit's own shading.
// envprobe makes a sky, envprefilter its GGX chain (KTX2, RGBA16F), DFG LUT (EXR) and SH (JSON); tests/js/
// viewer_capture.mjs serves web/ and those files on 127.0.0.1, opens the page, and saves the canvas (and, when asked
// for a window size, the whole viewport after resizing the window to it).
//
// SpheresMatchEnvkitSplitSum: a fixed camera, 640 x 160 pixels. Every pixel is shaded here by SplitSumIbl
// (split_sum.h) from the same files, the Lambertian sphere by the SH JSON's irradiance_over_pi through envkit's
// sh_basis, all through the page's display transform (exposure, Reinhard, sRGB, 8 bits), and compared: per sphere
// and for the background, the median absolute difference over the pixels and colour channels must be <= 1 of 255
// and at most 1% of them may differ by more than 8 of 255. A copy of the page whose shader reads the LUT's A and B
// the wrong way round must fail the same comparison, so the comparison is known to see a wrong split-sum.
//
// WindowFilledAndBackgroundBilinear: the page as a user opens it (default field of view and camera), the window
// resized to 1200 x 500 after loading. The viewport must show no black row and be the canvas itself, and the
// background must match envkit's bilinear lookup of level 0 closely enough that texel blocks would not: a copy of the
// page that magnifies level 0 with nearest filtering must fail the same bound.
#include <envkit/ibl/ktx2.h>
#include <envkit/ibl/sh.h>
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
// The background against envkit's bilinear lookup at 1200 x 500: at most this fraction of the values may differ by
// more than kBlockLevels. Nearest magnification puts a step of up to half a texel's gradient at every texel edge.
constexpr double kBlockLevels = 2.0;  // 8-bit levels
constexpr double kBlockFraction = 0.005;

// The scene the test asks the page for (URL parameters), and the geometry web/viewer.js builds from them: one
// sphere per roughness, then the Lambertian sphere (the SH JSON is given).
constexpr int kWidth = 640, kHeight = 160;
const std::vector<double> kRoughness = {0.0, 0.2, 0.45, 0.7, 1.0};
const Vec3 kF0(0.9, 0.6, 0.3);
const Vec3 kAlbedo(0.7, 0.5, 0.3);
constexpr double kExposure = 0.5, kFovDeg = 20.0, kCameraZ = 10.0, kSpacing = 2.5;
constexpr int kWindowWidth = 1200, kWindowHeight = 500;

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

// E(n) / pi from envprefilter's SH JSON (irradiance_over_pi, first three channels) through envkit's basis,
// clamped at 0 as the page clamps it.
struct ShIrradiance {
  int order = 0;
  std::vector<double> c[3];
  explicit ShIrradiance(const nlohmann::json& j) : order(j.at("order").get<int>()) {
    for (int ch = 0; ch < 3; ++ch)
      c[ch] = j.at("irradiance_over_pi")
                  .at("coefficients")
                  .at(j.at("channels").at(ch).get<std::string>())
                  .get<std::vector<double>>();
  }
  Vec3 operator()(const Vec3& n) const {
    double y[16];
    sh_basis(order, n, y);
    double e[3] = {0, 0, 0};
    for (int ch = 0; ch < 3; ++ch)
      for (int i = 0; i < sh_count(order); ++i) e[ch] += c[ch][i] * y[i];
    return Vec3(std::max(e[0], 0.0), std::max(e[1], 0.0), std::max(e[2], 0.0));
  }
};

struct Group {
  std::vector<double> diffs;  // |captured - reference| per pixel and channel, 8-bit levels
  double median() {
    if (diffs.empty()) return 0.0;
    std::nth_element(diffs.begin(), diffs.begin() + diffs.size() / 2, diffs.end());
    return diffs[diffs.size() / 2];
  }
  double above(double levels) const {
    return diffs.empty() ? 0.0
                         : double(std::count_if(diffs.begin(), diffs.end(), [&](double d) { return d > levels; })) /
                               double(diffs.size());
  }
  double outliers() const { return above(kOutlierLevels); }
};

// What viewer_capture.mjs saved: the canvas, the camera it was rendered from, and the viewport when a window size
// was asked for.
struct Capture {
  int width = 0, height = 0;
  Vec3 eye;
  double fov_deg = 0;
  std::vector<unsigned char> canvas;
  int window_width = 0, window_height = 0;
  std::vector<unsigned char> window;
};

class Viewer : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("envkit_viewer_" + std::to_string(::getpid()));
    fs::create_directories(dir_ / "data");
    chromium_ = find_chromium();
    // scripts/install-deps.sh installs chromium for the README's test command: its absence is a broken set-up, not
    // a skip.
    ASSERT_FALSE(chromium_.empty()) << "Debian's chromium is not installed (scripts/install-deps.sh installs it)";
    ASSERT_TRUE(fs::exists(web_ / "node_modules/three/build/three.module.js"))
        << "three is not installed in web/: run scripts/install-deps.sh (npm ci in web/)";
    const fs::path data = dir_ / "data";
    test::CommandResult r =
        test::run_tool("envprobe", {"default", "-o", (dir_ / "sky.exr").string(), "--size", "256x128"}, dir_);
    ASSERT_EQ(r.code, 0) << r.err;
    r = test::run_tool("envprefilter",
                       {(dir_ / "sky.exr").string(), "-o", (data / "sky_ggx.ktx2").string(), "--size", "64", "--lut",
                        (data / "dfg.exr").string(), "--lut-size", "64", "--sh", (data / "sky_sh.json").string(), "-q"},
                       dir_);
    ASSERT_EQ(r.code, 0) << r.err;
    Ktx2Texels chain = read_ktx2((data / "sky_ggx.ktx2").string());
    std::vector<double> roughness;
    std::stringstream list(chain.key_values.at("envkit:ibl_roughness"));
    for (std::string item; std::getline(list, item, ',');) roughness.push_back(std::stod(item));
    ibl_ = std::make_unique<SplitSumIbl>(std::move(chain.levels), roughness, read_image((data / "dfg.exr").string()));
    sh_ = std::make_unique<ShIrradiance>(nlohmann::json::parse(test::read_text(data / "sky_sh.json")));
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs the capture script on `web_root` with the scene's URL parameters plus `query`; `window` is "" or "WxH".
  Capture capture(const fs::path& web_root, const std::string& name, const std::string& query,
                  const std::string& window = "") {
    const std::string scene =
        "map=data/sky_ggx.ktx2&lut=data/dfg.exr&sh=data/sky_sh.json&static=1&roughness=" + join(kRoughness) +
        "&f0=" + join({kF0.x, kF0.y, kF0.z}) + "&albedo=" + join({kAlbedo.x, kAlbedo.y, kAlbedo.z}) +
        "&exposure=" + join({kExposure});
    const std::string script = std::string(ENVKIT_SOURCE_DIR) + "/tests/js/viewer_capture.mjs";
    const fs::path prefix = dir_ / name;
    std::vector<std::string> args = {script,        chromium_,       (dir_ / "data").string(),
                                     scene + query, prefix.string(), web_root.string()};
    if (!window.empty()) args.push_back(window);
    const test::CommandResult r = test::run_command("node", args, dir_);
    Capture c;
    EXPECT_EQ(r.code, 0) << r.err;
    if (r.code != 0) return c;
    const nlohmann::json info = nlohmann::json::parse(test::read_text(prefix.string() + ".json"));
    c.width = info.at("width");
    c.height = info.at("height");
    const std::vector<double> eye = info.at("camera").at("position");
    c.eye = Vec3(eye.at(0), eye.at(1), eye.at(2));
    c.fov_deg = info.at("camera").at("fov");
    const std::string bytes = test::read_text(prefix.string() + ".rgba");
    c.canvas.assign(bytes.begin(), bytes.end());
    EXPECT_EQ(c.canvas.size(), std::size_t(c.width) * c.height * 4);
    if (!window.empty()) {
      c.window_width = info.at("window_width");
      c.window_height = info.at("window_height");
      const std::string shot = test::read_text(prefix.string() + ".window.rgba");
      c.window.assign(shot.begin(), shot.end());
      EXPECT_EQ(c.window.size(), std::size_t(c.window_width) * c.window_height * 4);
    }
    return c;
  }

  // A copy of web/ whose `file` has the first `marked` text (which must exist) replaced by `by`.
  fs::path broken_copy(const std::string& name, const std::string& file, const std::string& marked,
                       const std::string& by) {
    const fs::path broken = dir_ / name;
    fs::create_directories(broken);
    for (const char* f : {"index.html", "viewer.js", "ibl.js", "shaders.js"})
      if (f != file) fs::copy_file(web_ / f, broken / f);
    fs::create_directory_symlink(web_ / "node_modules", broken / "node_modules");
    std::string text = test::read_text(web_ / file);
    const std::size_t at = text.find(marked);
    EXPECT_NE(at, std::string::npos) << "web/" << file << " no longer has '" << marked << "'";
    if (at != std::string::npos) text.replace(at, marked.size(), by);
    std::ofstream(broken / file) << text;
    return broken;
  }

  // Compares captured pixels with envkit's shading of the same scene, seen from the capture's camera (looking at
  // the origin, +Y up): one group per sphere (the Lambertian one last), then the background.
  std::vector<Group> compare(const Capture& c) {
    const int n = int(kRoughness.size()) + 1;
    std::vector<Group> groups(n + 1);
    if (c.canvas.empty()) return groups;
    const double t = std::tan(c.fov_deg * M_PI / 360.0), aspect = double(c.width) / c.height;
    const Vec3 forward = (-1.0 * c.eye).normalized();
    const Vec3 right = (forward % Vec3(0, 1, 0)).normalized(), up = right % forward;
    const double pixel = 2.0 * c.eye.length() * t / c.height;  // world size of a pixel at the spheres' distance
    for (int j = 0; j < c.height; ++j)
      for (int i = 0; i < c.width; ++i) {
        const double x = 2.0 * (i + 0.5) / c.width - 1.0, y = 1.0 - 2.0 * (j + 0.5) / c.height;
        const Vec3 d = (forward + x * aspect * t * right + y * t * up).normalized();
        int hit = -1;
        double hit_t = 1e30;
        bool near_rim = false;
        for (int k = 0; k < n; ++k) {
          const Vec3 centre((k - (n - 1) / 2.0) * kSpacing, 0, 0);
          const Vec3 oc = centre - c.eye;
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
          const Vec3 centre((hit - (n - 1) / 2.0) * kSpacing, 0, 0);
          const Vec3 nrm = (c.eye + hit_t * d - centre).normalized();
          if (hit < n - 1) {
            want = ibl_->specular(nrm, -1.0 * d, kRoughness[hit], kF0);
          } else {
            const Vec3 e = (*sh_)(nrm);
            want = Vec3(kAlbedo.x * e.x, kAlbedo.y * e.y, kAlbedo.z * e.z);
          }
        } else {
          want = ibl_->radiance(d, 0.0);
        }
        Group& g = groups[hit >= 0 ? hit : n];
        const unsigned char* got = &c.canvas[(std::size_t(j) * c.width + i) * 4];
        for (int ch = 0; ch < 3; ++ch) g.diffs.push_back(std::abs(got[ch] - display(want[ch])));
      }
    return groups;
  }

  const fs::path web_ = fs::path(ENVKIT_SOURCE_DIR) / "web";
  fs::path dir_;
  std::string chromium_;
  std::unique_ptr<SplitSumIbl> ibl_;
  std::unique_ptr<ShIrradiance> sh_;
};

std::string group_name(std::size_t k) {
  if (k < kRoughness.size()) return "sphere of roughness " + std::to_string(kRoughness[k]);
  return k == kRoughness.size() ? "Lambertian sphere (SH)" : "background";
}

TEST_F(Viewer, SpheresMatchEnvkitSplitSum) {
  const std::string camera = "&size=" + std::to_string(kWidth) + "x" + std::to_string(kHeight) +
                             "&fov=" + join({kFovDeg}) + "&camera=0,0," + join({kCameraZ});
  const Capture c = capture(web_, "viewer", camera);
  ASSERT_EQ(c.width, kWidth);
  ASSERT_EQ(c.height, kHeight);
  std::vector<Group> groups = compare(c);
  for (std::size_t k = 0; k < groups.size(); ++k) {
    const std::string what = group_name(k);
    ASSERT_GT(groups[k].diffs.size(), 300u) << what;
    std::printf("%s: %zu values, median |difference| %.2f of 255, %.2f%% above %.0f\n", what.c_str(),
                groups[k].diffs.size(), groups[k].median(), 100.0 * groups[k].outliers(), kOutlierLevels);
    EXPECT_LE(groups[k].median(), kMedianTolerance) << what;
    EXPECT_LE(groups[k].outliers(), kOutlierFraction) << what;
  }

  // The same page with A and B of the LUT swapped must fail the comparison on the rough spheres.
  const fs::path swapped = broken_copy("web_swapped_lut", "shaders.js", ".rg;  // ENVKIT_LUT_LOOKUP", ".gr;");
  std::vector<Group> wrong = compare(capture(swapped, "swapped", camera));
  int failing = 0;
  for (std::size_t k = 0; k < kRoughness.size(); ++k) {
    failing += wrong[k].median() > kMedianTolerance;
    std::printf("swapped LUT, sphere %zu: median |difference| %.2f of 255\n", k, wrong[k].median());
  }
  EXPECT_GE(failing, 3) << "a viewer with A and B swapped passes the comparison";
}

TEST_F(Viewer, WindowFilledAndBackgroundBilinear) {
  const std::string window = std::to_string(kWindowWidth) + "x" + std::to_string(kWindowHeight);
  const Capture c = capture(web_, "window", "", window);
  ASSERT_EQ(c.window_width, kWindowWidth);
  ASSERT_EQ(c.window_height, kWindowHeight);
  EXPECT_EQ(c.width, kWindowWidth) << "the canvas's drawing buffer does not follow the window";
  EXPECT_EQ(c.height, kWindowHeight) << "the canvas's drawing buffer does not follow the window";
  // No black row in the viewport (the map has no black row at this exposure), and the viewport shows the canvas.
  int black_rows = 0;
  for (int j = 0; j < c.window_height; ++j) {
    bool black = true;
    for (int i = 0; i < c.window_width && black; ++i) {
      const unsigned char* px = &c.window[(std::size_t(j) * c.window_width + i) * 4];
      black = px[0] <= 2 && px[1] <= 2 && px[2] <= 2;
    }
    black_rows += black;
  }
  std::printf("viewport %dx%d, canvas %dx%d, %d black rows\n", c.window_width, c.window_height, c.width, c.height,
              black_rows);
  EXPECT_EQ(black_rows, 0);
  if (c.width == c.window_width && c.height == c.window_height) {
    int largest = 0;
    for (std::size_t i = 0; i < c.window.size(); ++i)
      if (i % 4 != 3) largest = std::max(largest, std::abs(int(c.window[i]) - int(c.canvas[i])));
    std::printf("viewport vs canvas: largest difference %d of 255\n", largest);
    EXPECT_LE(largest, 1) << "the viewport is not the canvas";
  }

  // The background against envkit's bilinear lookup of level 0, at the default field of view.
  std::vector<Group> groups = compare(c);
  Group& background = groups.back();
  ASSERT_GT(background.diffs.size(), 100000u);
  std::printf("background (bilinear): %zu values, median %.2f of 255, %.3f%% above %.0f, %.3f%% above %.0f\n",
              background.diffs.size(), background.median(), 100.0 * background.above(kBlockLevels), kBlockLevels,
              100.0 * background.outliers(), kOutlierLevels);
  EXPECT_LE(background.median(), kMedianTolerance);
  EXPECT_LE(background.above(kBlockLevels), kBlockFraction) << "the background is not envkit's bilinear lookup";

  // Nearest magnification of level 0 must fail the same bound.
  const fs::path nearest =
      broken_copy("web_nearest", "ibl.js", "THREE.LinearFilter; // ENVKIT_CUBE_MAG_FILTER", "THREE.NearestFilter;");
  std::vector<Group> blocky = compare(capture(nearest, "nearest", "", window));
  Group& nearest_background = blocky.back();
  std::printf("background (nearest): median %.2f of 255, %.3f%% above %.0f, %.3f%% above %.0f\n",
              nearest_background.median(), 100.0 * nearest_background.above(kBlockLevels), kBlockLevels,
              100.0 * nearest_background.outliers(), kOutlierLevels);
  EXPECT_GT(nearest_background.above(kBlockLevels), kBlockFraction)
      << "a viewer magnifying level 0 with nearest filtering passes the background comparison";
}

}  // namespace
