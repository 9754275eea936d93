// Tests of the built tools envconvert, envinfo and envdiff, run as processes on small synthetic maps written
// with libenv: conversions and their metadata, directions through files and conventions, rotation, flux,
// exrenvmap interop, reports, exit codes, and one-line errors that leave no file behind.
#include <OpenImageIO/imageio.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "cli_support.h"

namespace fs = std::filesystem;
using envkit::Image;
using envkit::Vec3;
using envkit::test::CommandResult;
using nlohmann::json;

namespace {

const char* const kKinds[] = {"latlong", "cube", "mirrorball", "angular", "octahedral", "paraboloid"};
const char* const kLayouts[] = {"vstrip", "hstrip", "hcross", "vcross"};

/// A w x h centre-sampled lat-long whose texel (i, j) holds rgb(direction of its centre, i, j).
Image latlong(int w, int h, const std::function<Vec3(const Vec3&, int, int)>& rgb) {
  const envkit::LatLongMap param(w, h);
  Image img(w, h, 3);
  img.channel_names = {"R", "G", "B"};
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      Vec3 d;
      param.to_direction(envkit::Vec2(i + 0.5, j + 0.5), d);
      const Vec3 v = rgb(d, i, j);
      for (int c = 0; c < 3; ++c) img.at(i, j, c) = static_cast<float>(v[c]);
    }
  return img;
}

/// Red: 1 + octant number (x > 0) + 2 (y > 0) + 4 (z > 0); green 2; blue 0.5.
double octant_value(const Vec3& d) { return 1.0 + (d.x > 0) + 2.0 * (d.y > 0) + 4.0 * (d.z > 0); }
Image octant_map(int w = 32, int h = 16) {
  return latlong(w, h, [](const Vec3& d, int, int) { return Vec3(octant_value(d), 2.0, 0.5); });
}

/// A dim sky (0.1) with red 1000 in the 2x2 texels of a 32x16 lat-long around `target` (one of the
/// axis directions that fall on texel corners: +-X, +-Z).
Image bright_block(const Vec3& target, int channel = 0) {
  return latlong(32, 16, [&](const Vec3& d, int, int) {
    Vec3 v(0.1, 0.1, 0.1);
    if (envkit::angle_between(d, target) < 0.25) v[channel] = 1000.0;  // texel centres are 0.14 rad away
    return v;
  });
}

/// Power-weighted mean direction of channel c in the envkit world.
Vec3 bright_direction(const envkit::EnvMap& m, int c = 0) {
  const envkit::SolidAngleTable omega(*m.param);
  Vec3 sum(0, 0, 0);
  for (int j = 0; j < m.image.height; ++j)
    for (int i = 0; i < m.image.width; ++i) {
      Vec3 d;
      if (!m.param->to_direction(envkit::Vec2(i + 0.5, j + 0.5), d)) continue;
      sum += envkit::apply(m.to_world(), d) * (omega(i, j) * m.image.at(i, j, c));
    }
  return sum.normalized();
}

/// Value of channel c of the texel that sees world direction d.
float value_at(const envkit::EnvMap& m, const Vec3& d, int c = 0) {
  const envkit::Vec2 p = m.param->to_image(envkit::apply(envkit::transposed(m.to_world()), d));
  const int i = std::clamp(static_cast<int>(p.x), 0, m.image.width - 1);
  const int j = std::clamp(static_cast<int>(p.y), 0, m.image.height - 1);
  return m.image.at(i, j, c);
}

double power(const envkit::EnvMap& m, int c = 0) { return envkit::total_power(m.image, *m.param)[c]; }

/// Writes float pixels with OIIO directly (for files envkit refuses to write: NaN, 5 channels).
void write_with_oiio(const std::string& path, int w, int h, int channels, const std::vector<float>& pixels) {
  OIIO::ImageSpec spec(w, h, channels, OIIO::TypeDesc::FLOAT);
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out && out->open(path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, pixels.data()) && out->close());
}

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ::unsetenv("OCIO");
    ::unsetenv("ENVKIT_OCIO_CONFIG");
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() / ("envkit_cli_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(root_);
    fs::create_directories(root_ / "w");
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }

  /// Path in the work directory (captured output lives outside it, so listings show only map files).
  std::string path(const std::string& name) const { return (root_ / "w" / name).string(); }
  std::set<std::string> listing() const {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(root_ / "w")) names.insert(e.path().filename().string());
    return names;
  }

  /// Writes a lat-long tagged as such (no "assumed" line) unless `tagged` is false.
  std::string write_latlong(const std::string& name, const Image& img, bool tagged = true) const {
    envkit::WriteOptions opt;
    if (tagged) opt.metadata["envkit:parameterization"] = "latlong";
    envkit::write_image(path(name), img, opt);
    return path(name);
  }

  CommandResult tool(const std::string& name, const std::vector<std::string>& args) const {
    return envkit::test::run_tool(name, args, root_);
  }
  /// Runs a tool that must succeed.
  CommandResult ok(const std::string& name, const std::vector<std::string>& args) const {
    CommandResult r = tool(name, args);
    EXPECT_EQ(r.code, 0) << name << " failed: " << r.err;
    return r;
  }
  /// Runs envconvert expecting exit 1 with ONE stderr line that names `file` and contains `problem`.
  void expect_one_line_error(const std::vector<std::string>& args, const std::string& file,
                             const std::string& problem) const {
    const std::set<std::string> before = listing();
    const CommandResult r = tool("envconvert", args);
    EXPECT_EQ(r.code, 1) << r.err;
    const auto lines = r.err_lines();
    ASSERT_EQ(lines.size(), 1u) << r.err;
    EXPECT_EQ(lines[0].rfind("envconvert: ", 0), 0u) << lines[0];
    EXPECT_NE(lines[0].find(file), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find(problem), std::string::npos) << lines[0];
    EXPECT_EQ(listing(), before) << "an output or temp file appeared";
  }

  envkit::EnvMap load(const std::string& p) const { return envkit::load_envmap(p); }

  fs::path root_;
};

// ---- conversions ----------------------------------------------------------------------------------------------

TEST_F(CliTest, ConvertsToEveryKindAndBackWithMetadata) {
  const std::string in = write_latlong("in.exr", octant_map(64, 32));
  const Vec3 octants[] = {{1, 1, 1},  {-1, 1, 1},  {1, -1, 1},  {-1, -1, 1},
                          {1, 1, -1}, {-1, 1, -1}, {1, -1, -1}, {-1, -1, -1}};
  for (const char* kind : kKinds) {
    SCOPED_TRACE(kind);
    const std::string out = path(std::string("to_") + kind + ".exr");
    const CommandResult r = ok("envconvert", {in, "-o", out, "--to", kind, "--size", "32"});
    EXPECT_EQ(r.err.find("assumed"), std::string::npos) << "the tagged input needs no guess: " << r.err;
    const Image img = envkit::read_image(out);
    int w = 0, h = 0;
    envkit::natural_image_size(envkit::parse_kind(kind), 32, envkit::CubeLayout::VerticalStrip, w, h);
    EXPECT_EQ(img.width, w);
    EXPECT_EQ(img.height, h);
    EXPECT_EQ(img.metadata.at("envkit:parameterization"), kind);
    EXPECT_EQ(img.metadata.at("envkit:convention"), "envkit");
    EXPECT_EQ(img.metadata.at("envkit:filter"), "area");
    EXPECT_EQ(img.metadata.at("envkit:source"), "in.exr");
    EXPECT_EQ(img.metadata.count("envkit:layout"), std::string(kind) == "cube" ? 1u : 0u);

    // Back to lat-long (detected from the metadata): every octant keeps its value.
    const std::string back = path(std::string("back_") + kind + ".exr");
    ok("envconvert", {out, "-o", back, "--to", "latlong", "--size", "32", "--quiet"});
    const envkit::EnvMap m = load(back);
    EXPECT_EQ(m.image.width, 64);
    for (const Vec3& o : octants) EXPECT_NEAR(value_at(m, o.normalized()), octant_value(o), 0.3) << o;
    EXPECT_NEAR(power(m, 1), 2.0 * envkit::kFourPi, 0.01 * 2.0 * envkit::kFourPi);
  }
}

TEST_F(CliTest, EveryCubeLayoutAndSixFilesRoundTrip) {
  const std::string in = write_latlong("in.exr", octant_map());
  for (const char* layout : kLayouts) {
    SCOPED_TRACE(layout);
    const std::string out = path(std::string("cube_") + layout + ".exr");
    ok("envconvert", {in, "-o", out, "--to", "cube", "--layout", layout, "--size", "8", "-q"});
    const Image img = envkit::read_image(out);
    int w = 0, h = 0;
    envkit::layout_size(envkit::parse_layout(layout), 8, w, h);
    EXPECT_EQ(img.width, w);
    EXPECT_EQ(img.height, h);
    EXPECT_EQ(img.metadata.at("envkit:layout"), layout);
    // Read back (layout from the metadata): the octants are where they belong. (Running the tools costs
    // ~0.3 s a process, mostly loading OIIO's libraries; the way back through the tool is tested for crosses.)
    const envkit::EnvMap cube = load(out);
    EXPECT_NEAR(value_at(cube, Vec3(1, 1, 1).normalized()), 8.0, 0.3);
    EXPECT_NEAR(value_at(cube, Vec3(-1, -1, -1).normalized()), 1.0, 0.3);
    if (std::string(layout).find("cross") != std::string::npos) {
      const std::string back = path(std::string("back_") + layout + ".exr");
      ok("envconvert", {out, "-o", back, "--to", "latlong", "--size", "16", "-q"});
      const envkit::EnvMap m = load(back);
      EXPECT_NEAR(value_at(m, Vec3(1, 1, 1).normalized()), 8.0, 0.3);
      EXPECT_NEAR(value_at(m, Vec3(-1, -1, -1).normalized()), 1.0, 0.3);
      EXPECT_NEAR(power(m, 1), 2.0 * envkit::kFourPi, 0.01 * 2.0 * envkit::kFourPi) << "blank cells are not light";
    }
  }
  // Six face files and back.
  ok("envconvert", {in, "-o", path("face_%.exr"), "--to", "cube", "--size", "8", "-q"});
  for (const char* f : {"+X", "-X", "+Y", "-Y", "+Z", "-Z"}) {
    const Image face = envkit::read_image(path(std::string("face_") + f + ".exr"));
    EXPECT_EQ(face.width, 8);
    EXPECT_EQ(face.height, 8);
    EXPECT_EQ(face.metadata.at("envkit:face"), f);
  }
  ok("envconvert", {path("face_%.exr"), "-o", path("from_faces.exr"), "--to", "latlong", "--size", "16", "-q"});
  const envkit::EnvMap m = load(path("from_faces.exr"));
  EXPECT_NEAR(value_at(m, Vec3(1, -1, 1).normalized()), 6.0, 0.3);
}

TEST_F(CliTest, DefaultSizeKeepsTheTexelDensityAndGuessesAreReported) {
  const std::string in = write_latlong("in.exr", octant_map(64, 32), /*tagged=*/false);
  const CommandResult r = ok("envconvert", {in, "-o", path("cube.exr"), "--to", "cube"});
  EXPECT_NE(r.err.find("envconvert: " + in + ": assumed latlong from the 2:1 aspect ratio; pass --from to override"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("latlong 64x32"), std::string::npos) << "input description: " << r.err;
  EXPECT_EQ(r.err.find('%'), std::string::npos) << "no progress bar: small, and stderr is not a terminal";
  const Image cube = envkit::read_image(path("cube.exr"));
  EXPECT_EQ(cube.width, 18);  // 6 N^2 ~ 64 x 32: N = 18.5 -> 18 (or 19)
  EXPECT_EQ(cube.height, 6 * cube.width);
  // --quiet keeps the guess (it may make the output wrong) but drops the description.
  const CommandResult q = ok("envconvert", {in, "-o", path("q.exr"), "--to", "octahedral", "--quiet"});
  EXPECT_EQ(q.err_lines().size(), 1u) << q.err;
  EXPECT_EQ(envkit::read_image(path("q.exr")).width, 45);  // N^2 = 2048
}

TEST_F(CliTest, ProgressBarOnlyWhenAsked) {
  const std::string in = write_latlong("in.exr", octant_map());
  const CommandResult p = ok("envconvert", {in, "-o", path("p.exr"), "--to", "cube", "--size", "16", "--progress"});
  EXPECT_NE(p.err.find("100%"), std::string::npos) << p.err;
  const CommandResult q =
      ok("envconvert", {in, "-o", path("q.exr"), "--to", "cube", "--size", "16", "--progress", "--quiet"});
  EXPECT_EQ(q.err, "");
}

// ---- directions through files -------------------------------------------------------------------------------

TEST_F(CliTest, OpenExrCubeHasTheBrightTexelOnItsPlusXFace) {
  const std::string in = write_latlong("in.exr", bright_block(Vec3(1, 0, 0)));
  ok("envconvert", {in, "-o", path("cube.exr"), "--to", "cube", "--convention", "openexr", "--size", "8", "-q"});
  const Image img = envkit::read_image(path("cube.exr"));
  ASSERT_EQ(img.width, 8);
  ASSERT_EQ(img.height, 48);
  EXPECT_EQ(img.metadata.at("envmap"), "cube");  // the OpenEXR attribute
  EXPECT_EQ(img.metadata.at("envkit:convention"), "openexr");
  double face_sum[6] = {};
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 8; ++x) face_sum[y / 8] += img.at(x, y, 0);
  EXPECT_EQ(std::max_element(face_sum, face_sum + 6) - face_sum, 0) << "face +X (rows 0..7) must be brightest";
  // Its centre: the four middle texels of the +X face hold the block.
  EXPECT_GT(img.at(3, 3, 0) + img.at(4, 4, 0), 100.0f);
}

TEST_F(CliTest, GlSixFilesPutTheBrightTexelInThePlusXFile) {
  const std::string in = write_latlong("in.exr", bright_block(Vec3(1, 0, 0)));
  ok("envconvert", {in, "-o", path("gl_%.exr"), "--to", "cube", "--convention", "gl", "--size", "8", "-q"});
  std::string brightest;
  double best = -1;
  for (const char* f : {"+X", "-X", "+Y", "-Y", "+Z", "-Z"}) {
    const Image face = envkit::read_image(path(std::string("gl_") + f + ".exr"));
    EXPECT_EQ(face.metadata.at("envkit:convention"), "gl");
    double sum = 0;
    for (int t = 0; t < 64; ++t) sum += face.pixels[t * 3];
    if (sum > best) best = sum, brightest = f;
  }
  EXPECT_EQ(brightest, "+X");
}

TEST_F(CliTest, BlenderLatLongPutsEnvkitPlusXAtTheImageCentre) {
  // Red block at envkit +X, green block at envkit -Z. Blender (x, y, z) = envkit (x, -z, y): red is +X_b, which
  // Blender's equirect shows at the image centre; green is +Y_b, shown at u = 1/4.
  Image img = bright_block(Vec3(1, 0, 0), 0);
  const Image green = bright_block(Vec3(0, 0, -1), 1);
  for (std::size_t t = 0; t < img.texel_count(); ++t) img.pixels[t * 3 + 1] = green.pixels[t * 3 + 1];
  const std::string in = write_latlong("in.exr", img);
  ok("envconvert", {in, "-o", path("blender.exr"), "--to", "latlong", "--convention", "blender", "--size", "16", "-q"});
  const Image out = envkit::read_image(path("blender.exr"));
  ASSERT_EQ(out.width, 32);
  // Blender's own formula per pixel: u = (x + 0.5) / W, v = 1 - (y + 0.5) / H (bottom-up), phi = pi - 2 pi u,
  // theta = pi - pi v. Power-weighted mean direction of each channel in Blender's frame.
  for (int c : {0, 1}) {
    Vec3 sum(0, 0, 0);
    int best_x = 0, best_y = 0;
    for (int y = 0; y < out.height; ++y)
      for (int x = 0; x < out.width; ++x) {
        const double u = (x + 0.5) / out.width, v = 1.0 - (y + 0.5) / out.height;
        const double phi = envkit::kPi - envkit::kTwoPi * u, theta = envkit::kPi - envkit::kPi * v;
        const Vec3 b(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
        sum += b * (out.at(x, y, c) * std::sin(theta));
        if (out.at(x, y, c) > out.at(best_x, best_y, c)) best_x = x, best_y = y;
      }
    const Vec3 expected = c == 0 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
    EXPECT_GT(sum.normalized() ^ expected, 0.99) << "channel " << c << " mean direction " << sum.normalized();
    EXPECT_TRUE(best_y == 7 || best_y == 8) << best_y;
    const int first_column = c == 0 ? 15 : 7;  // the image centre; u = 1/4
    EXPECT_TRUE(best_x == first_column || best_x == first_column + 1) << "channel " << c << ": column " << best_x;
  }
  // And envkit reads it back in its own world.
  EXPECT_GT(bright_direction(load(path("blender.exr")), 0) ^ Vec3(1, 0, 0), 0.99);
}

TEST_F(CliTest, RotateYaw90MovesPlusZToPlusX) {
  const std::string in = write_latlong("in.exr", bright_block(Vec3(0, 0, 1)));
  ok("envconvert", {in, "-o", path("rot.exr"), "--to", "latlong", "--size", "16", "--rotate", "90,0,0", "-q"});
  const envkit::EnvMap m = load(path("rot.exr"));
  EXPECT_GT(bright_direction(m) ^ Vec3(1, 0, 0), 0.99) << bright_direction(m);
  EXPECT_GT(value_at(m, Vec3(1, 0, 0)), 100.0f);
  EXPECT_LT(value_at(m, Vec3(0, 0, 1)), 1.0f);
  // Cube output too: the +X face.
  ok("envconvert", {in, "-o", path("rot_cube.exr"), "--to", "cube", "--size", "8", "--rotate", "90,0,0", "-q"});
  EXPECT_GT(bright_direction(load(path("rot_cube.exr"))) ^ Vec3(1, 0, 0), 0.99);
}

// ---- flux, envdiff, envinfo -----------------------------------------------------------------------------------

TEST_F(CliTest, AreaConversionKeepsPowerPerEnvdiff) {
  // A smooth sky plus one very bright texel (a sun).
  const std::string in =
      write_latlong("in.exr", latlong(64, 32, [](const Vec3& d, int i, int j) {
                      const double sun = (i == 21 && j == 9) ? 5e4 : 0.0;
                      return Vec3(0.2 + 0.8 * std::max(d.y, 0.0) + sun, 0.3 + 0.1 * d.x, 0.5 + sun / 2);
                    }));
  for (const char* kind : {"cube", "octahedral", "mirrorball"}) {
    SCOPED_TRACE(kind);
    const std::string out = path(std::string("area_") + kind + ".exr");
    ok("envconvert", {in, "-o", out, "--to", kind, "--size", "24", "-q"});
    const CommandResult r = ok("envdiff", {in, out, "--json", "--metric", "power", "--fail-above", "0.001"});
    const json j = json::parse(r.out);
    ASSERT_EQ(j["power"].size(), 3u);
    for (const auto& ch : j["power"]) EXPECT_LT(ch["relative_difference"].get<double>(), 1e-3) << ch.dump();
  }
}

TEST_F(CliTest, EnvdiffReportsAndExitCodes) {
  const std::string a = write_latlong("a.exr", latlong(32, 16, [](const Vec3&, int, int) { return Vec3(1, 1, 1); }));
  const std::string b =
      write_latlong("b.exr", latlong(32, 16, [](const Vec3& d, int, int) {
                      return Vec3(d.y > 0.9 ? 3.0 : 1.1, 1.1, 1.1);  // 10% brighter, and a hot cap around +Y in red
                    }));
  const CommandResult text = ok("envdiff", {a, b, "--fail-above", "0.1"});  // relmse 0.06 (below): exit 0
  for (const char* word : {"rmse", "relmse", "max |B - A|", "power A", "power B", "direction", "<= 0.1: ok"})
    EXPECT_NE(text.out.find(word), std::string::npos) << word << "\n" << text.out;
  // Same grid and nearest filter: B reaches A's texels unchanged, so the numbers are exact.
  const json j = json::parse(ok("envdiff", {a, b, "--json", "--filter", "nearest"}).out);
  // relMSE, solid-angle weighted and averaged over channels: 0.01 / (1 + 0.01) for a 10% error against R = 1,
  // and 2^2 / (1 + 0.01) in red over the cap (rows 0 and 1: polar angle < pi/8).
  const double cap = (1.0 - std::cos(envkit::kPi / 8)) / 2.0;
  EXPECT_NEAR(j["relmse"].get<double>(), (0.01 / 1.01 * (3.0 - cap) + cap * 4.0 / 1.01) / 3.0, 1e-5);
  EXPECT_NEAR(j["rmse"].get<double>(), std::sqrt((0.01 * (3.0 - cap) + cap * 4.0) / 3.0), 1e-5);
  EXPECT_NEAR(j["max_abs_error"]["value"].get<double>(), 2.0, 1e-4);
  EXPECT_EQ(j["max_abs_error"]["channel"], "R");
  EXPECT_GT(j["max_abs_error"]["direction"][1].get<double>(), 0.9);  // the cap is around +Y
  EXPECT_NEAR(j["power"][1]["relative_difference"].get<double>(), 0.1, 1e-6);
  EXPECT_NEAR(j["compared_solid_angle"].get<double>(), envkit::kFourPi, 1e-9);

  EXPECT_EQ(tool("envdiff", {a, b, "--fail-above", "0.001"}).code, 3);
  EXPECT_EQ(tool("envdiff", {a, b, "--metric", "max", "--fail-above", "1.5"}).code, 3);
  const CommandResult failed = tool("envdiff", {a, b, "--metric", "power", "--fail-above", "0.01", "--json"});
  EXPECT_EQ(failed.code, 3);
  EXPECT_TRUE(json::parse(failed.out)["failed"].get<bool>());
  // Different parameterizations: a cube B against a lat-long A.
  ok("envconvert", {b, "-o", path("b_cube.exr"), "--to", "cube", "--size", "16", "-q"});
  EXPECT_EQ(tool("envdiff", {b, path("b_cube.exr"), "--metric", "power", "--fail-above", "0.001"}).code, 0);
  // Errors are one line with exit 1.
  const CommandResult missing = tool("envdiff", {a, path("absent.exr")});
  EXPECT_EQ(missing.code, 1);
  ASSERT_EQ(missing.err_lines().size(), 1u) << missing.err;
  EXPECT_NE(missing.err.find("absent.exr: no such file"), std::string::npos) << missing.err;
}

TEST_F(CliTest, EnvinfoReportsPowerStatisticsAndNonFiniteCounts) {
  // A constant RGB (1, 2, 3) lat-long with 3 NaN, 2 +Inf and 1 -Inf values, and 4 negative ones.
  const int w = 16, h = 8;
  std::vector<float> px(w * h * 3);
  for (std::size_t t = 0; t < px.size(); ++t) px[t] = float(t % 3 + 1);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  px[0] = px[10] = px[20] = nan;
  px[30] = px[40] = inf;
  px[50] = -inf;
  px[60] = px[61] = px[62] = px[70] = -0.5f;
  write_with_oiio(path("bad.exr"), w, h, 3, px);

  const CommandResult text = ok("envinfo", {path("bad.exr")});
  for (const char* word : {"power", "mean radiance", "3 NaN", "2 +Inf", "1 -Inf", "negative", "latlong 16x8",
                           "assumed from the 2:1 aspect ratio"})
    EXPECT_NE(text.out.find(word), std::string::npos) << word << "\n" << text.out;

  const json j = json::parse(ok("envinfo", {path("bad.exr"), "--json"}).out);
  EXPECT_EQ(j["nonfinite"]["nan"], 3);
  EXPECT_EQ(j["nonfinite"]["posinf"], 2);
  EXPECT_EQ(j["nonfinite"]["neginf"], 1);
  EXPECT_EQ(j["negative"], 4);
  EXPECT_EQ(j["width"], 16);
  EXPECT_EQ(j["channels"], json({"R", "G", "B"}));
  EXPECT_EQ(j["parameterization"]["kind"], "latlong");
  EXPECT_TRUE(j["parameterization"]["assumed"].get<bool>());
  EXPECT_NEAR(j["solid_angle"].get<double>(), envkit::kFourPi, 1e-9);
  const json& g = j["statistics"][1];  // green: no bad value lands on it except -0.5 at 61 and 70
  EXPECT_EQ(g["channel"], "G");
  EXPECT_EQ(g["max"].get<double>(), 2.0);
  EXPECT_EQ(g["min"].get<double>(), -0.5);
  envkit::ReadOptions zero;
  zero.nonfinite = envkit::NonFinitePolicy::Zero;
  const double green_power =
      envkit::total_power(envkit::read_image(path("bad.exr"), zero), envkit::LatLongMap(w, h))[1];
  EXPECT_NEAR(g["power"].get<double>(), green_power, 1e-9);
  EXPECT_NEAR(g["mean_radiance"].get<double>(), green_power / envkit::kFourPi, 1e-9);

  // A clean constant map: power 4 pi L, mean radiance L.
  write_latlong("ones.exr", latlong(16, 8, [](const Vec3&, int, int) { return Vec3(1, 2, 3); }));
  const json c = json::parse(ok("envinfo", {path("ones.exr"), "--json"}).out);
  EXPECT_NEAR(c["statistics"][2]["power"].get<double>(), 3 * envkit::kFourPi, 1e-5);
  EXPECT_NEAR(c["statistics"][2]["mean_radiance"].get<double>(), 3.0, 1e-6);
  EXPECT_FALSE(c["parameterization"]["assumed"].get<bool>());
}

// ---- exrenvmap interop ----------------------------------------------------------------------------------------

TEST_F(CliTest, OpenExrOutputsAreReadByExrenvmapAndBack) {
  const std::string in = write_latlong("in.exr", latlong(64, 32, [](const Vec3& d, int, int) {
                                         return Vec3(1.0 + d.y, 1.0 + 0.5 * d.x, 1.0 + 0.5 * d.z);
                                       }));
  ok("envconvert", {in, "-o", path("ours_ll.exr"), "--to", "latlong", "--convention", "openexr", "--size", "16", "-q"});
  ok("envconvert", {in, "-o", path("ours_cube.exr"), "--to", "cube", "--convention", "openexr", "--size", "16", "-q"});
  EXPECT_EQ(envkit::read_image(path("ours_ll.exr")).metadata.at("envmap"), "latlong");
  EXPECT_EQ(envkit::read_image(path("ours_cube.exr")).metadata.at("envmap"), "cube");
  ASSERT_TRUE(fs::exists("/usr/bin/exrenvmap"))
      << "/usr/bin/exrenvmap missing: scripts/install-deps.sh installs Debian's openexr";

  const CommandResult c = envkit::test::run_command(
      "/usr/bin/exrenvmap", {"-c", "-w", "16", path("ours_ll.exr"), path("theirs_cube.exr")}, root_);
  ASSERT_EQ(c.code, 0) << c.err;
  const CommandResult l = envkit::test::run_command(
      "/usr/bin/exrenvmap", {"-l", "-w", "32", path("ours_cube.exr"), path("theirs_ll.exr")}, root_);
  ASSERT_EQ(l.code, 0) << l.err;
  // exrenvmap copies our envkit:* attributes into its output: its envmap attribute must win over them.
  ok("envconvert", {path("theirs_cube.exr"), "-o", path("back_ll.exr"), "--to", "latlong", "--size", "16", "-q"});
  ok("envconvert", {path("theirs_ll.exr"), "-o", path("back_cube.exr"), "--to", "cube", "--size", "16", "-q"});
  const std::vector<std::pair<std::string, std::string>> pairs = {{"ours_ll.exr", "back_ll.exr"},
                                                                  {"ours_cube.exr", "back_cube.exr"}};
  for (const auto& [ours, back] : pairs) {
    const envkit::EnvMap a = load(path(ours)), b = load(path(back));
    EXPECT_EQ(b.convention, "openexr") << back;
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(power(b, ch) / power(a, ch), 1.0, 0.03) << back << " channel " << ch;
    EXPECT_GT(bright_direction(b, 0) ^ Vec3(0, 1, 0), 0.9) << back << ": red is brighter up";
  }
}

TEST_F(CliTest, CompressionAndHalfReachTheOpenExrFile) {
  const std::string in =
      write_latlong("in.exr", latlong(32, 16, [](const Vec3& d, int, int) { return Vec3(1.0 + d.y, 1.0, 1.0); }));
  ok("envconvert",
     {in, "-o", path("none.exr"), "--to", "cube", "--size", "8", "--compression", "none", "--half", "-q"});
  ok("envconvert", {in, "-o", path("piz.exr"), "--to", "cube", "--size", "8", "--compression", "piz", "-q"});
  const auto spec_of = [&](const std::string& name) {
    auto file = OIIO::ImageInput::open(path(name));
    EXPECT_TRUE(file) << name;
    return file ? file->spec() : OIIO::ImageSpec();
  };
  EXPECT_EQ(spec_of("none.exr").get_string_attribute("compression"), "none");
  EXPECT_EQ(spec_of("none.exr").format, OIIO::TypeDesc::HALF);
  EXPECT_EQ(spec_of("piz.exr").get_string_attribute("compression"), "piz");
  EXPECT_EQ(spec_of("piz.exr").format, OIIO::TypeDesc::FLOAT);
  // An unknown OpenEXR compression is a usage error before anything is read or written.
  const CommandResult bad = tool("envconvert", {in, "-o", path("bad.exr"), "--to", "cube", "--compression", "zap"});
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("--compression"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(path("bad.exr")));
}

// ---- bad input: one line, exit 1, no file -------------------------------------------------------------------

TEST_F(CliTest, NonFiniteInputFailsUnlessFixed) {
  std::vector<float> px(16 * 8 * 3, 1.0f);
  px[5] = std::numeric_limits<float>::quiet_NaN();
  px[7] = std::numeric_limits<float>::infinity();
  write_with_oiio(path("nan.exr"), 16, 8, 3, px);
  expect_one_line_error({path("nan.exr"), "-o", path("out.exr"), "--to", "cube"}, "nan.exr",
                        "2 non-finite values (1 NaN, 1 Inf); pass --fix-nonfinite zero|clamp");
  const CommandResult r = ok("envconvert", {path("nan.exr"), "-o", path("out.exr"), "--to", "cube", "--from", "latlong",
                                            "--fix-nonfinite", "zero"});
  EXPECT_NE(r.err.find("replaced 2 non-finite values"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(path("out.exr")));
}

TEST_F(CliTest, NegativeValuesAreAWarning) {
  write_latlong("neg.exr", latlong(16, 8, [](const Vec3& d, int, int) { return Vec3(d.x, 1, 1); }));
  const CommandResult r = ok("envconvert", {path("neg.exr"), "-o", path("out.exr"), "--to", "cube", "-q"});
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find("envconvert: warning: " + path("neg.exr") + ": 64 negative values"), std::string::npos) << r.err;
}

TEST_F(CliTest, UnreadableInputsAreOneLineErrors) {
  // Truncated EXR.
  envkit::WriteOptions raw;
  raw.compression = "none";
  envkit::write_image(path("full.exr"), octant_map(128, 64), raw);
  const std::string bytes = envkit::test::read_text(path("full.exr"));
  fs::remove(path("full.exr"));
  std::ofstream(path("cut.exr"), std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  expect_one_line_error({path("cut.exr"), "-o", path("out.exr"), "--to", "cube"}, "cut.exr", "cannot read");
  // Garbage.
  std::ofstream(path("junk.exr"), std::ios::binary) << "this is not an image";
  expect_one_line_error({path("junk.exr"), "-o", path("out.exr"), "--to", "cube"}, "junk.exr", "cannot read");
  // Five channels.
  write_with_oiio(path("five.exr"), 8, 4, 5, std::vector<float>(8 * 4 * 5, 1.0f));
  expect_one_line_error({path("five.exr"), "-o", path("out.exr"), "--to", "cube"}, "five.exr",
                        "unsupported channel count 5");
  // Missing file.
  expect_one_line_error({path("absent.exr"), "-o", path("out.exr"), "--to", "cube"}, "absent.exr", "no such file");
}

TEST_F(CliTest, CubeFacesOfDifferentSizesAreRefused) {
  for (const char* f : {"+X", "-X", "+Y", "-Y", "+Z", "-Z"}) {
    const int n = std::string(f) == "+Z" ? 8 : 4;
    Image face(n, n, 3);
    std::fill(face.pixels.begin(), face.pixels.end(), 1.0f);
    envkit::write_image(path(std::string("f_") + f + ".exr"), face);
  }
  expect_one_line_error({path("f_%.exr"), "-o", path("out.exr"), "--to", "latlong"}, "f_+Z.exr",
                        "all six faces must have the same size");
}

TEST_F(CliTest, FromContradictingTheAspectRatioIsRefused) {
  Image square(8, 8, 3);
  envkit::write_image(path("square.exr"), square);
  expect_one_line_error({path("square.exr"), "-o", path("out.exr"), "--to", "cube", "--from", "latlong"}, "square.exr",
                        "contradicts --from latlong");
}

TEST_F(CliTest, OutputOverInputIsRefusedInAnySpelling) {
  const std::string in = write_latlong("in.exr", octant_map());
  fs::create_directories(root_ / "w" / "sub");
  for (const std::string& out : {in, path("sub/../in.exr")})
    expect_one_line_error({in, "-o", out, "--to", "latlong"}, out, "same as input");
  // --force allows it (the write is atomic, the input was read first).
  ok("envconvert", {in, "-o", path("sub/../in.exr"), "--to", "latlong", "--size", "8", "--force", "-q"});
  EXPECT_EQ(envkit::read_image(in).width, 16);
  fs::remove(path("sub"));
  // Through a face pattern too: writing one of the input faces.
  ok("envconvert", {in, "-o", path("face_%.exr"), "--to", "cube", "--size", "4", "-q"});
  const auto before = listing();
  const CommandResult r = tool("envconvert", {path("face_%.exr"), "-o", path("face_+Y.exr"), "--to", "cube"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("same as input"), std::string::npos) << r.err;
  EXPECT_EQ(listing(), before);
}

TEST_F(CliTest, UnwritableOutputDirectoryIsRefusedBeforeReading) {
  const std::string in = write_latlong("in.exr", octant_map());
  expect_one_line_error({in, "-o", path("missing/out.exr"), "--to", "cube"}, "missing/out.exr", "does not exist");
  // A parent that is a regular file (root passes access(W_OK), so a read-only directory would not do).
  expect_one_line_error({in, "-o", path("in.exr/out.exr"), "--to", "cube"}, "in.exr/out.exr", "not a directory");
  // Checked before the input is read: a broken input is not even opened.
  std::ofstream(path("junk.exr")) << "junk";
  expect_one_line_error({path("junk.exr"), "-o", path("missing/out.exr"), "--to", "cube"}, "missing/out.exr",
                        "does not exist");
}

TEST_F(CliTest, UsageErrorsExitTwoWithAClearMessage) {
  const std::string in = write_latlong("in.exr", octant_map());
  const CommandResult kind = tool("envconvert", {in, "-o", path("out.exr"), "--to", "globe"});
  EXPECT_EQ(kind.code, 2);
  EXPECT_NE(kind.err.find("--to: unknown parameterization 'globe'"), std::string::npos) << kind.err;
  const CommandResult half = tool("envconvert", {in, "-o", path("out.hdr"), "--to", "cube", "--half"});
  EXPECT_EQ(half.code, 2);
  EXPECT_NE(half.err.find("--half"), std::string::npos) << half.err;
  const CommandResult faces = tool("envconvert", {in, "-o", path("f_%.exr"), "--to", "latlong"});
  EXPECT_EQ(faces.code, 2);
  EXPECT_NE(faces.err.find("needs --to cube"), std::string::npos) << faces.err;
  EXPECT_EQ(tool("envconvert", {in, "--to", "cube"}).code, 2);  // no -o
  EXPECT_EQ(tool("envdiff", {in, in, "--metric", "psnr"}).code, 2);
  EXPECT_EQ(tool("envinfo", {in, "--from", "sphere"}).code, 2);
  EXPECT_EQ(listing(), std::set<std::string>{"in.exr"});
  // --help documents the options and shows examples.
  for (const char* t : {"envconvert", "envinfo", "envdiff"}) {
    const CommandResult help = ok(t, {"--help"});
    EXPECT_NE(help.out.find("Examples:"), std::string::npos) << t;
    EXPECT_NE(help.out.find("Exit status"), std::string::npos) << t;
    if (std::string(t) == "envdiff") {
      EXPECT_NE(help.out.find("relmse  mean((I - R)^2 / (R^2 + 0.01))"), std::string::npos) << help.out;
    }
  }
}

}  // namespace
