// envrender on the command line: a tiny successful render, and bad input (malformed JSON, unknown keys and
// materials, missing meshes, degenerate triangles, a camera inside geometry, missing and stale tables): exit
// code 1, one line on stderr naming the file, the line and the problem, and no output file.
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputPart.h>
#include <OpenEXR/ImfMultiPartInputFile.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/render/scene_loader.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "cli_support.h"

using namespace envkit;
namespace fs = std::filesystem;

namespace {

/// Mean of the green channel of an image file.
double mean_green(const fs::path& file) {
  const Image beauty = read_image(file.string());
  double sum = 0.0;
  for (int y = 0; y < beauty.height; ++y)
    for (int x = 0; x < beauty.width; ++x) sum += beauty.at(x, y, 1);
  return sum / double(beauty.width * beauty.height);
}

class RenderCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("envkit_render_cli_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name) << text;
    return dir_ / name;
  }
  test::CommandResult envrender(std::vector<std::string> args) {
    args.push_back("--threads");
    args.push_back("2");
    return test::run_tool("envrender", args, dir_);
  }
  /// A valid scene with a constant probe; `extra_shape` is appended to the shapes, `camera` replaces the camera.
  static std::string scene(
      const std::string& extra_shape = "", const std::string& materials_extra = "",
      const std::string& camera = R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])",
      const std::string& environment = R"("probe": "constant", "radiance": 0.5, "size": [32, 16])") {
    return std::string("{\n") + "  \"camera\": {" + camera + ", \"fov\": 40, \"resolution\": [16, 8]},\n" +
           "  \"environment\": {" + environment + "},\n" + "  \"materials\": {\n" +
           "    \"white\": {\"type\": \"diffuse\", \"albedo\": 0.5}" + materials_extra + "\n" + "  },\n" +
           "  \"shapes\": [\n" +
           "    {\"type\": \"sphere\", \"center\": [0, 0.5, 0], \"radius\": 0.5, \"material\": \"white\"}" +
           extra_shape + "\n" + "  ]\n" + "}\n";
  }
  /// Runs a bad scene; expects exit 1, one stderr line containing every fragment, and no output.
  void expect_error(const fs::path& scene_file, const std::vector<std::string>& fragments,
                    std::vector<std::string> extra = {}) {
    const fs::path out = dir_ / "out.exr";
    std::vector<std::string> args = {"--scene", scene_file.string(), "-o", out.string(), "--spp", "1"};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = envrender(args);
    EXPECT_EQ(r.code, 1) << r.err;
    ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
    for (const auto& f : fragments)
      EXPECT_NE(r.err.find(f), std::string::npos) << "missing '" << f << "' in: " << r.err;
    EXPECT_FALSE(fs::exists(out));
    EXPECT_FALSE(fs::exists(dir_ / "out.png"));
  }

  fs::path dir_;
};

}  // namespace

TEST_F(RenderCli, RendersASmallSceneWithEveryOutput) {
  const auto file = write("ok.json", scene());
  const fs::path out = dir_ / "ok.exr";
  const auto r = envrender({"--scene", file.string(), "-o", out.string(), "--spp", "4", "--quiet"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_TRUE(fs::exists(out));
  EXPECT_TRUE(fs::exists(dir_ / "ok.png"));
  const Image png = read_image((dir_ / "ok.png").string());
  EXPECT_EQ(png.width, 16);
  EXPECT_EQ(png.height, 8);
  // The EXR holds the mean (part 0, what read_image reads) and the variance AOV and sample count (part 1).
  const Image beauty = read_image(out.string());
  EXPECT_EQ(beauty.channels, 3);
  Imf::MultiPartInputFile exr(out.string().c_str());
  ASSERT_EQ(exr.parts(), 2);
  for (const char* channel : {"R", "G", "B"})
    EXPECT_NE(exr.header(0).channels().findChannel(channel), nullptr) << channel;
  for (const char* channel : {"variance.R", "variance.G", "variance.B", "samples"})
    EXPECT_NE(exr.header(1).channels().findChannel(channel), nullptr) << channel;
  EXPECT_EQ(exr.header(1).channels().findChannel("seconds"), nullptr);  // only with --pixel-seconds
  const Imath::Box2i window = exr.header(1).dataWindow();
  const int w = window.max.x - window.min.x + 1, h = window.max.y - window.min.y + 1;
  ASSERT_EQ(w, 16);
  ASSERT_EQ(h, 8);
  std::vector<float> samples(std::size_t(w * h)), variance(std::size_t(w * h));
  Imf::FrameBuffer frame;
  frame.insert("samples",
               Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(samples.data()), sizeof(float), sizeof(float) * w));
  frame.insert("variance.G",
               Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(variance.data()), sizeof(float), sizeof(float) * w));
  Imf::InputPart aov(exr, 1);
  aov.setFrameBuffer(frame);
  aov.readPixels(window.min.y, window.max.y);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_EQ(samples[i], 4.0f);
    EXPECT_TRUE(std::isfinite(variance[i]) && variance[i] >= 0.0f);
  }
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x) EXPECT_TRUE(std::isfinite(beauty.at(x, y, 1)) && beauty.at(x, y, 1) > 0.0f);
}

// --pixel-seconds adds the time of each pixel's samples to the aov part: positive and finite, adding up to no more
// than the render's seconds times its two threads; the beauty part is the same bits as without it.
TEST_F(RenderCli, PixelSecondsAddATimeChannel) {
  const auto file = write("ok.json", scene());
  const fs::path plain = dir_ / "plain.exr", timed = dir_ / "timed.exr";
  ASSERT_EQ(envrender({"--scene", file.string(), "-o", plain.string(), "--spp", "8", "-q"}).code, 0);
  const auto r = envrender({"--scene", file.string(), "-o", timed.string(), "--spp", "8", "-q", "--pixel-seconds"});
  ASSERT_EQ(r.code, 0) << r.err;
  const Image a = read_image(plain.string()), b = read_image(timed.string());
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  for (std::size_t i = 0; i < a.pixels.size(); ++i) EXPECT_EQ(a.pixels[i], b.pixels[i]) << i;
  Imf::MultiPartInputFile exr(timed.string().c_str());
  ASSERT_NE(exr.header(1).channels().findChannel("seconds"), nullptr);
  const Imath::Box2i window = exr.header(1).dataWindow();
  const int w = window.max.x - window.min.x + 1, h = window.max.y - window.min.y + 1;
  std::vector<float> seconds(std::size_t(w * h));
  Imf::FrameBuffer frame;
  frame.insert("seconds",
               Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(seconds.data()), sizeof(float), sizeof(float) * w));
  Imf::InputPart aov(exr, 1);
  aov.setFrameBuffer(frame);
  aov.readPixels(window.min.y, window.max.y);
  double sum = 0.0;
  for (float s : seconds) {
    EXPECT_TRUE(std::isfinite(s) && s > 0.0f) << s;
    sum += s;
  }
  const auto* attr = exr.header(1).findTypedAttribute<Imf::StringAttribute>("envkit:seconds");
  ASSERT_NE(attr, nullptr);
  EXPECT_LE(sum, 2.0 * std::stod(attr->value()) + 1e-3);
}

TEST_F(RenderCli, CropWritesTheWindowOnly) {
  const auto file = write("ok.json", scene());
  const fs::path out = dir_ / "crop.exr";
  const auto r = envrender({"--scene", file.string(), "-o", out.string(), "--spp", "2", "--crop", "4,2,12,6", "-q"});
  ASSERT_EQ(r.code, 0) << r.err;
  const Image png = read_image((dir_ / "crop.png").string());
  EXPECT_EQ(png.width, 8);
  EXPECT_EQ(png.height, 4);
}

TEST_F(RenderCli, UsageErrorsExitWithTwo) {
  EXPECT_EQ(envrender({"--strategy", "magic"}).code, 2);
  EXPECT_EQ(envrender({"--spp", "0"}).code, 2);
  EXPECT_EQ(envrender({"--light-method", "best"}).code, 2);
  // A valid method the product strategies cannot use is an error, not ignored.
  const auto r = envrender({"--light-method", "alias", "--spp", "1", "--resolution", "8x4"});
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--light-method alias: the product strategies refine the hierarchical table"), std::string::npos)
      << r.err;
  EXPECT_EQ(envrender({"--sun-samples", "-1"}).code, 2);
  EXPECT_EQ(envrender({"--sun-samples", "1.5"}).code, 2);
}

// A constant map has no compensated importance: its compensated tables are the plain ones. Only the strategy that
// draws from them says so.
TEST_F(RenderCli, TheCompensatedTablesWarningIsForMisCompensatedOnly) {
  const auto flat = write("flat.json", scene());
  const std::string warning = "the compensated tables are the plain ones";
  auto r = envrender({"--scene", flat.string(), "-o", (dir_ / "mis.exr").string(), "--spp", "1", "--strategy", "mis"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find(warning), std::string::npos) << r.err;
  r = envrender(
      {"--scene", flat.string(), "-o", (dir_ / "comp.exr").string(), "--spp", "1", "--strategy", "mis-compensated"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("warning: compensated importance max(f - mean, 0) is zero everywhere"), std::string::npos)
      << r.err;
}

// A map with a sun: envrender says it samples the sun apart and records the samples; --sun-samples 0 samples the
// map as one table; both images agree within their noise. A map without a sun records 0.
TEST_F(RenderCli, SunSamplesAreReportedAndRecorded) {
  const auto sunny = write("sunny.json", scene("", "", R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])",
                                               R"("probe": "sun", "radiance": 2e4, "sky": 0.5, "radius_deg": 0.5, )"
                                               R"("elevation_deg": 50, "azimuth_deg": 30, "size": [256, 128])"));
  const auto overcast = write("overcast.json", scene());
  const auto recorded = [&](const fs::path& out) {
    Imf::MultiPartInputFile exr(out.string().c_str());
    const auto* attr = exr.header(0).findTypedAttribute<Imf::StringAttribute>("envkit:sun_samples");
    return attr ? attr->value() : std::string("missing");
  };
  const fs::path split = dir_ / "split.exr", whole = dir_ / "whole.exr", none = dir_ / "none.exr";
  auto r = envrender({"--scene", sunny.string(), "-o", split.string(), "--spp", "256", "--bake"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("sampling the sun apart from the rest of the map"), std::string::npos) << r.err;
  EXPECT_EQ(recorded(split), "1");
  r = envrender({"--scene", sunny.string(), "-o", whole.string(), "--spp", "256", "--bake", "--sun-samples", "0"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("sampling the sun apart"), std::string::npos) << r.err;
  EXPECT_EQ(recorded(whole), "0");
  EXPECT_NEAR(mean_green(split), mean_green(whole), 0.03 * mean_green(whole));
  r = envrender({"--scene", overcast.string(), "-o", none.string(), "--spp", "1", "--sun-samples", "2", "-q"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(recorded(none), "0");
}

// A map whose sun the camera clipped: envrender renders it and warns that sunlit surfaces come out too dark; the
// same sun unclipped gets no warning.
TEST_F(RenderCli, ClippedSunIsWarnedAbout) {
  const probes::SunProbe probe(Vec3(0.3, 0.5, 0.8), 1.5 * kPi / 180.0, Vec3(1e5), Vec3(0.05));
  for (const bool clip : {true, false}) {
    Image image = probes::rasterize(probe, LatLongMap(256, 128));
    if (clip)
      for (float& v : image.pixels) v = std::min(v, 200.0f);  // a camera that saturated at 200
    const std::string name = clip ? "clipped.exr" : "full.exr";
    write_image((dir_ / name).string(), image);
    const auto file = write(
        "sun.json", scene("", "", R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])", "\"image\": \"" + name + "\""));
    const auto r = envrender({"--scene", file.string(), "-o", (dir_ / "out.exr").string(), "--spp", "1", "--bake"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.err.find(name + ": the sun is clipped flat") != std::string::npos, clip) << r.err;
  }
}

// envbake --tables hierarchical,sun stores the sun split; envinfo reports the stored sun; envrender reads the split
// instead of building it and renders the same pixels, bit for bit.
TEST_F(RenderCli, AStoredSunSplitRendersTheImageOfOneBuiltAtLoad) {
  const probes::SunProbe probe(Vec3(0.3, 0.5, 0.8), 1.5 * kPi / 180.0, Vec3(1e5), Vec3(0.05));
  write_image((dir_ / "sky.exr").string(), probes::rasterize(probe, LatLongMap(256, 128)));
  const auto file = write("sun.json", scene("", "", R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])",
                                            R"("image": "sky.exr", "tables": "sky.envtbl")"));
  fs::path out[2];
  for (const bool stored : {false, true}) {
    std::vector<std::string> bake = {(dir_ / "sky.exr").string(), "-o", (dir_ / "sky.envtbl").string(), "-q", "-f"};
    if (stored) bake.insert(bake.end(), {"--tables", "hierarchical,sun"});
    const auto baked = test::run_tool("envbake", bake, dir_);
    ASSERT_EQ(baked.code, 0) << baked.err;
    const auto info = test::run_tool("envinfo", {(dir_ / "sky.envtbl").string()}, dir_);
    ASSERT_EQ(info.code, 0) << info.err;
    EXPECT_EQ(info.out.find("sun (of the importance)") != std::string::npos, stored) << info.out;
    out[stored] = dir_ / (stored ? "stored.exr" : "built.exr");
    const auto r = envrender({"--scene", file.string(), "-o", out[stored].string(), "--spp", "4"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.err.find("sampling the sun apart"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("the split read from") != std::string::npos, stored) << r.err;
    EXPECT_EQ(r.err.find("envbake --tables hierarchical,sun stores it") != std::string::npos, !stored) << r.err;
  }
  const Image built = read_image(out[0].string()), stored = read_image(out[1].string());
  ASSERT_EQ(built.pixels.size(), stored.pixels.size());
  EXPECT_TRUE(std::equal(built.pixels.begin(), built.pixels.end(), stored.pixels.begin()));
  // The hint names the tables the render samples.
  const auto baked = test::run_tool(
      "envbake", {(dir_ / "sky.exr").string(), "-o", (dir_ / "sky.envtbl").string(), "-q", "-f", "--tables", "cdf"},
      dir_);
  ASSERT_EQ(baked.code, 0) << baked.err;
  const auto r = envrender({"--scene", file.string(), "-o", (dir_ / "cdf.exr").string(), "--spp", "1", "--strategy",
                            "mis", "--light-method", "cdf"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("envbake --tables cdf,sun stores it"), std::string::npos) << r.err;
}

// A sun that is all the map's light (a black sky): the split would leave an empty rest of the map, whose uniform
// fallback draws the sun's texels too and doubled the sunlight. It is not split: the image is the one rendered
// without sun samples.
TEST_F(RenderCli, ASunThatIsAllTheLightIsNotCountedTwice) {
  const probes::SunProbe probe(Vec3(0.3, 0.5, 0.8), 1.0 * kPi / 180.0, Vec3(1e3), Vec3(0.0));
  write_image((dir_ / "sun.exr").string(), probes::rasterize(probe, LatLongMap(256, 128)));
  const auto file =
      write("sun.json", scene("", "", R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])", R"("image": "sun.exr")"));
  fs::path out[2];
  for (const int sun_samples : {0, 1}) {
    out[sun_samples] = dir_ / ("sun" + std::to_string(sun_samples) + ".exr");
    const auto r = envrender({"--scene", file.string(), "-o", out[sun_samples].string(), "--spp", "16", "--bake",
                              "--strategy", "light", "--sun-samples", std::to_string(sun_samples)});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.err.find("sampling the sun apart"), std::string::npos) << r.err;
  }
  const Image a = read_image(out[0].string()), b = read_image(out[1].string());
  ASSERT_EQ(a.pixels.size(), b.pixels.size());
  EXPECT_TRUE(std::equal(a.pixels.begin(), a.pixels.end(), b.pixels.begin()));
}

// The product strategies say what they built and render the image mis renders, within its noise.
TEST_F(RenderCli, ProductStrategiesNameTheirTablesAndAgreeWithMis) {
  const auto file = write("ok.json", scene());
  double mean[3] = {0.0, 0.0, 0.0};
  int k = 0;
  for (const char* strategy : {"mis", "product", "product-mis"}) {
    const fs::path out = dir_ / (std::string("strategy_") + strategy + ".exr");
    const auto r = envrender({"--scene", file.string(), "-o", out.string(), "--spp", "64", "--strategy", strategy});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.err.find("product tables for the scene's") != std::string::npos, k > 0) << strategy << ": " << r.err;
    mean[k++] = mean_green(out);
  }
  EXPECT_NEAR(mean[1], mean[0], 0.05 * mean[0]);
  EXPECT_NEAR(mean[2], mean[0], 0.05 * mean[0]);
}

TEST_F(RenderCli, MalformedJsonNamesTheLine) {
  std::string text = scene();
  text.replace(text.find("\"materials\": {"), 14, "\"materials\": {,");  // line 4
  const auto file = write("bad.json", text);
  expect_error(file, {"bad.json:4:", "malformed JSON"});
}

TEST_F(RenderCli, UnknownKeyNamesLineAndKey) {
  std::string text = scene();
  text.replace(text.find("\"fov\": 40"), 9, "\"fov\": 40, \"zoom\": 2");  // line 2
  const auto file = write("key.json", text);
  expect_error(file, {"key.json:2:", "camera.zoom", "unknown key 'zoom'"});
}

TEST_F(RenderCli, UnknownMaterialNamesTheShape) {
  const auto file = write("mat.json", scene(R"(,
    {"type": "sphere", "center": [2, 0.5, 0], "radius": 0.5, "material": "gold"})"));
  expect_error(file, {"mat.json:9:", "shapes[1].material", "unknown material 'gold'"});
}

TEST_F(RenderCli, UnknownMaterialTypeIsAnError) {
  const auto file = write("type.json", scene("", R"(,
    "glass": {"type": "dielectric"})"));
  expect_error(file, {"type.json:6:", "materials.glass.type", "unknown material type 'dielectric'"});
}

TEST_F(RenderCli, UnknownShadowingIsAnError) {
  const auto file = write("shadowing.json", scene("", R"(,
    "steel": {"type": "conductor", "roughness": 0.3, "shadowing": "smith"})"));
  expect_error(file, {"shadowing.json:6:", "materials.steel.shadowing", "unknown value 'smith'",
                      "height-correlated, separable"});
}

TEST_F(RenderCli, MissingMeshIsAnError) {
  const auto file = write("mesh.json", scene(R"(,
    {"type": "mesh", "file": "nowhere.obj", "material": "white"})"));
  expect_error(file, {"mesh.json:9:", "shapes[1].file", "nowhere.obj", "does not exist"});
}

// A symlink loop among the meshes is a scene error like a missing mesh: the scene file, the line, the field, the
// file and the cause, not a bare file-system exception.
TEST_F(RenderCli, MeshSymlinkLoopNamesTheSceneLineAndField) {
  fs::create_symlink("b.obj", dir_ / "a.obj");
  fs::create_symlink("a.obj", dir_ / "b.obj");
  const auto file = write("loop.json", scene(R"(,
    {"type": "mesh", "file": "a.obj", "material": "white"})"));
  expect_error(file, {"loop.json:9: shapes[1].file: mesh file '", "a.obj': ", std::strerror(ELOOP)});
}

// A "\u0000" in a file name: refused as such (cut at the NUL, the name would silently name another file).
TEST_F(RenderCli, NulInAFileNameIsNamed) {
  write("a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const auto mesh = write("nul.json", scene(R"(,
    {"type": "mesh", "file": "a.obj\u0000.png", "material": "white"})"));
  expect_error(mesh, {"nul.json:9: shapes[1].file: file name 'a.obj\\x00.png' contains a NUL character"});
  const auto image = write("nul_image.json", scene("", "", R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])",
                                                   R"("image": "sky\u0000.exr", "tables": "sky.envtbl")"));
  expect_error(image, {"nul_image.json:3: environment.image: file name 'sky\\x00.exr' contains a NUL character"});
}

// User text echoed in a message is cut: a 2 MB unknown key (or material name, or value) gives a line of a few
// hundred characters that still names the scene, the line and the start of the key.
TEST_F(RenderCli, HugeKeysAndValuesAreCutInMessages) {
  const std::string huge(2 << 20, 'k');
  std::string text = scene();
  text.replace(text.find("\"fov\": 40"), 9, "\"fov\": 40, \"" + huge + "\": 2");  // line 2
  const auto key = write("key.json", text);
  expect_error(key, {"key.json:2: camera." + std::string(60, 'k') + "... (2097152 bytes): unknown key '"});
  const auto material = write("material.json", scene(R"(,
    {"type": "sphere", "center": [2, 0.5, 0], "radius": 0.5, "material": ")" +
                                                     huge + R"("})"));
  expect_error(material, {"material.json:9: shapes[1].material: unknown material '" + std::string(60, 'k') +
                          "... (2097152 bytes)'"});
  const auto malformed = write("malformed.json", "{\"" + huge + "\" 1}");
  expect_error(malformed, {"malformed.json:1: malformed JSON: "});
  for (const auto& file : {key, material, malformed}) {
    const auto r = envrender({"--scene", file.string(), "-o", (dir_ / "out.exr").string()});
    EXPECT_LT(r.err.size(), 1000u) << file;
  }
}

// A missing required key is named as the field, on the line of the object that lacks it.
TEST_F(RenderCli, MissingKeyIsTheField) {
  std::string text = scene();
  const std::string position = "\"position\": [0, 1, -5], ";
  text.replace(text.find(position), position.size(), "");  // line 2
  const auto file = write("nopos.json", text);
  expect_error(file, {"nopos.json:2: camera.position: missing key 'position'"});
}

// A scene path that loops (a symlink to itself) is named with the cause.
TEST_F(RenderCli, SceneSymlinkLoopIsNamed) {
  fs::create_symlink("self.json", dir_ / "self.json");
  const auto r = envrender({"--scene", (dir_ / "self.json").string(), "-o", (dir_ / "out.exr").string()});
  EXPECT_EQ(r.code, 1) << r.err;
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find("self.json: cannot read the scene file: " + std::string(std::strerror(ELOOP))),
            std::string::npos)
      << r.err;
}

TEST_F(RenderCli, DegenerateTrianglesAreReported) {
  write("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n");
  const auto file = write("deg.json", scene(R"(,
    {"type": "mesh", "file": "flat.obj", "material": "white"})"));
  expect_error(file, {"deg.json:9:", "flat.obj", "1 degenerate triangle", "triangle 0"});
}

TEST_F(RenderCli, CameraInsideASphereIsAnError) {
  const auto file = write("inside.json", scene("", "", R"("position": [0, 0.6, 0], "look_at": [0, 0.5, 3])"));
  expect_error(file, {"inside.json:", "camera.position", "inside", "shapes[0]"});
}

TEST_F(RenderCli, CameraInsideAClosedMeshIsAnError) {
  // A closed box (outward-facing triangles) around the camera.
  write("box.obj",
        "v -4 -4 -8\nv 4 -4 -8\nv 4 4 -8\nv -4 4 -8\nv -4 -4 8\nv 4 -4 8\nv 4 4 8\nv -4 4 8\n"
        "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 8 7\nf 4 7 3\nf 1 5 8\nf 1 8 4\nf 2 3 7\nf 2 7 6\n");
  const auto file = write("box.json", scene(R"(,
    {"type": "mesh", "file": "box.obj", "material": "white"})"));
  expect_error(file, {"box.json:", "camera.position", "inside", "box.obj"});
}

TEST_F(RenderCli, MissingAndStaleTablesAreErrorsUnlessBaked) {
  // An environment image and tables baked from a different image.
  LatLongMap grid(32, 16);
  write_image((dir_ / "sky.exr").string(), probes::rasterize(probes::ConstantProbe(Vec3(0.5)), grid));
  write_image((dir_ / "other.exr").string(), probes::rasterize(probes::ConstantProbe(Vec3(0.7)), grid));
  // envbake records the source file's hash; tables baked from other.exr are stale for sky.exr.
  const auto baked =
      test::run_tool("envbake", {(dir_ / "other.exr").string(), "-o", (dir_ / "sky.envtbl").string(), "-q"}, dir_);
  ASSERT_EQ(baked.code, 0) << baked.err;

  const auto missing = write(
      "missing.json", scene("", "", R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])", R"("image": "sky.exr")"));
  expect_error(missing, {"missing.json:3:", "environment", "tables", "--bake"});

  const auto stale = write("stale.json", scene("", "", R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])",
                                               R"("image": "sky.exr", "tables": "sky.envtbl")"));
  expect_error(stale, {"stale.json:3:", "environment.tables", "sky.envtbl", "stale", "--bake"});

  // --bake bakes in memory and says so.
  const fs::path out = dir_ / "baked.exr";
  const auto r = envrender({"--scene", stale.string(), "-o", out.string(), "--spp", "1", "--bake"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("baked sampling tables in memory"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(out));

  // Fresh tables (envbake) load without --bake; mis-compensated needs their compensated twins.
  const auto rebaked =
      test::run_tool("envbake", {(dir_ / "sky.exr").string(), "-o", (dir_ / "sky.envtbl").string(), "-q"}, dir_);
  ASSERT_EQ(rebaked.code, 0) << rebaked.err;
  const auto fresh = envrender({"--scene", stale.string(), "-o", out.string(), "--spp", "1", "-q"});
  EXPECT_EQ(fresh.code, 0) << fresh.err;
  fs::remove(out);
  fs::remove(dir_ / "baked.png");
  expect_error(stale, {"sky.exr", "no hierarchical-compensated table", "--bake"}, {"--strategy", "mis-compensated"});
}

// The same file read with another convention: the content hash matches, but the tables' directions are those of
// the other frame. envrender must refuse them (with --bake it bakes in the scene's frame), and accept tables baked
// with the scene's convention.
TEST_F(RenderCli, TablesOfAnotherConventionAreRefused) {
  LatLongMap grid(32, 16);
  write_image((dir_ / "sky.exr").string(), probes::rasterize(probes::ConstantProbe(Vec3(0.5)), grid));
  const auto scene_file =
      write("blender.json", scene("", "", R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])",
                                  R"("image": "sky.exr", "tables": "sky.envtbl", "convention": "blender")"));
  const auto bake = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = {(dir_ / "sky.exr").string(), "-o", (dir_ / "sky.envtbl").string(), "-q", "-f"};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = test::run_tool("envbake", args, dir_);
    ASSERT_EQ(r.code, 0) << r.err;
  };
  bake({});
  expect_error(scene_file, {"blender.json:3:", "sky.envtbl", "convention", "--bake"});
  const fs::path out = dir_ / "out.exr";
  const auto baked = envrender({"--scene", scene_file.string(), "-o", out.string(), "--spp", "1", "--bake", "-q"});
  EXPECT_EQ(baked.code, 0) << baked.err;
  bake({"--from-convention", "blender"});
  const auto matching = envrender({"--scene", scene_file.string(), "-o", out.string(), "--spp", "1", "-q", "-f"});
  EXPECT_EQ(matching.code, 0) << matching.err;
}

TEST_F(RenderCli, HealpixTablesRenderWithEveryTableStrategy) {
  // A HEALPix map (envkit metadata says so) and tables baked on its own texels.
  WriteOptions wo;
  wo.metadata["envkit:parameterization"] = "healpix";
  write_image((dir_ / "hp.exr").string(), probes::rasterize(probes::ConstantProbe(Vec3(0.5)), HealpixMap(4)), wo);
  const auto baked = test::run_tool(
      "envbake", {(dir_ / "hp.exr").string(), "-o", (dir_ / "hp.envtbl").string(), "--param", "healpix", "-q"}, dir_);
  ASSERT_EQ(baked.code, 0) << baked.err;
  const auto file = write("hp.json", scene("", "", R"("position": [0, 1, -5], "look_at": [0, 0.5, 0])",
                                           R"("image": "hp.exr", "tables": "hp.envtbl")"));
  const fs::path out = dir_ / "out.exr";
  double reference = 0.0;
  for (const char* strategy : {"mis", "light", "product", "product-mis"}) {
    const auto r =
        envrender({"--scene", file.string(), "-o", out.string(), "--spp", "16", "--strategy", strategy, "-q"});
    ASSERT_EQ(r.code, 0) << strategy << ": " << r.err;
    const double mean = mean_green(out);
    if (reference == 0.0) reference = mean;
    EXPECT_NEAR(mean, reference, 0.03 * reference) << strategy;
    fs::remove(out);
    fs::remove(dir_ / "out.png");
  }
}

TEST_F(RenderCli, SceneFilesShippedInTheRepositoryLoad) {
  for (const char* name : {"default.json", "overcast.json", "sunny.json"}) {
    const fs::path file = fs::path(ENVKIT_SOURCE_DIR) / "renderer" / "scenes" / name;
    ASSERT_TRUE(fs::exists(file)) << file;
    render::SceneLoadOptions options;
    options.width = 8;
    options.height = 4;
    EXPECT_NO_THROW(render::load_scene_file(file.string(), options)) << name;
  }
  // default.json is the built-in default scene.
  std::ifstream in(fs::path(ENVKIT_SOURCE_DIR) / "renderer" / "scenes" / "default.json");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), render::default_scene_json());
}
