// envprefilter run as a process: every output kind, its metadata (KTX2 key/value data read by ktx-parse), the SH
// JSON, the LUT's stored values, exit codes and one-line errors that leave no output behind.
#include <envkit/envmap/envmap.h>
#include <envkit/ibl/dfg.h>
#include <envkit/ibl/sh.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/latlong.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cli_support.h"
#include "prefilter_support.h"

using namespace envkit;
using namespace envkit::testing;
namespace fs = std::filesystem;

namespace {

class PrefilterCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("envkit_prefilter_cli_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    const EnvMap map = latlong_env(64, smooth_sky);
    input_ = (dir_ / "sky.exr").string();
    write_image(input_, map.image);
  }
  void TearDown() override { fs::remove_all(dir_); }
  test::CommandResult run(const std::vector<std::string>& args) {
    return test::run_command(std::string(ENVKIT_BIN_DIR) + "/envprefilter", args, dir_);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
  std::string input_;
};

TEST_F(PrefilterCli, WritesEveryOutput) {
  const test::CommandResult r = run({input_,
                                     "-o",
                                     path("ggx.ktx2"),
                                     "--size",
                                     "16",
                                     "--mapping",
                                     "filament",
                                     "--sh",
                                     path("sh.json"),
                                     "--sh-order",
                                     "3",
                                     "--sh-window",
                                     "hanning",
                                     "--irradiance",
                                     path("irr.dds"),
                                     "--irradiance-size",
                                     "4",
                                     "--lut",
                                     path("lut.png"),
                                     "--lut-size",
                                     "8",
                                     "-q"});
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* f : {"ggx.ktx2", "sh.json", "irr.dds", "lut.png"}) EXPECT_TRUE(fs::exists(dir_ / f)) << f;
  // The chain's metadata, read by ktx-parse.
  const std::string script = std::string(ENVKIT_SOURCE_DIR) + "/tests/js/ktx_dump.mjs";
  const test::CommandResult k = test::run_command("node", {script, path("ggx.ktx2")}, dir_);
  ASSERT_EQ(k.code, 0) << k.err;
  const nlohmann::json kj = nlohmann::json::parse(k.out);
  EXPECT_EQ(kj["levelCount"], 5);
  EXPECT_EQ(kj["faceCount"], 6);
  EXPECT_EQ(kj["keyValue"]["envkit:ibl_roughness_mapping"], "filament");
  EXPECT_EQ(kj["keyValue"]["envkit:ibl_roughness"].get<std::string>().substr(0, 2), "0,");
  // envinfo describes the KTX2 and DDS outputs from their headers.
  const test::CommandResult info =
      test::run_command(std::string(ENVKIT_BIN_DIR) + "/envinfo", {path("ggx.ktx2")}, dir_);
  EXPECT_EQ(info.code, 0) << info.err;
  EXPECT_NE(info.out.find("ktx2 rgba16f, 16x16, cube (6 faces), 5 levels"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("envkit:ibl_roughness_mapping: filament"), std::string::npos) << info.out;
  const test::CommandResult dds =
      test::run_command(std::string(ENVKIT_BIN_DIR) + "/envinfo", {path("irr.dds"), "--json"}, dir_);
  EXPECT_EQ(dds.code, 0) << dds.err;
  const nlohmann::json dj = nlohmann::json::parse(dds.out);
  EXPECT_EQ(dj["container"], "dds");
  EXPECT_EQ(dj["width"], 4);
  EXPECT_EQ(dj["faces"], 6);
  // SH JSON.
  const nlohmann::json sh = nlohmann::json::parse(test::read_text(dir_ / "sh.json"));
  EXPECT_EQ(sh["order"], 3);
  EXPECT_EQ(sh["window"], "hanning");
  EXPECT_EQ(sh["radiance"]["coefficients"]["R"].size(), 16u);
  // The LUT PNG stores values linearly in 16 bits.
  ReadOptions raw;
  raw.colorspace = "raw";
  const Image lut = read_image(path("lut.png"), raw);
  ASSERT_EQ(lut.width, 8);
  const DfgValue d = dfg_integrate((2 + 0.5) / 8, (5 + 0.5) / 8);
  EXPECT_NEAR(lut.at(2, 5, 0), d.scale, 1.0 / 65535);
  EXPECT_NEAR(lut.at(2, 5, 1), d.bias, 1.0 / 65535);
}

TEST_F(PrefilterCli, ExrChainWritesOneFilePerLevel) {
  const test::CommandResult r = run({input_, "-o", path("level%.exr"), "--size", "8", "--levels", "3", "-q"});
  ASSERT_EQ(r.code, 0) << r.err;
  for (int m = 0; m < 3; ++m) {
    const Image level = read_image(path("level" + std::to_string(m) + ".exr"));
    EXPECT_EQ(level.width, 8 >> m);
    EXPECT_EQ(level.metadata.at("envkit:ibl_level"), std::to_string(m));
  }
  EXPECT_FALSE(fs::exists(dir_ / "level3.exr"));
}

// Every order the library projects is offered: the file holds the library's coefficients for the input map, and
// an order past the library's limit is a usage error naming the option.
TEST_F(PrefilterCli, ShOrdersUpToTheLibrarysLimit) {
  const test::CommandResult r = run({input_, "--sh", path("sh8.json"), "--sh-order", "8", "-q"});
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream in(path("sh8.json"));
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["order"], 8);
  EXPECT_EQ(j["coefficients_per_channel"], 81);
  EnvMap map;  // the file the tool read, as it read it (envkit convention: the map frame is the world's)
  map.param = std::make_unique<LatLongMap>(64, 32);
  map.image = read_image(input_);
  const ShCoefficients want = project_sh(map.ref(), 8);
  const std::vector<double> got = j["radiance"]["coefficients"]["R"].get<std::vector<double>>();
  ASSERT_EQ(got.size(), 81u);
  for (int i = 0; i < 81; ++i) EXPECT_NEAR(got[std::size_t(i)], want.radiance[0][std::size_t(i)], 1e-6) << i;
  const test::CommandResult bad = run({input_, "--sh", path("sh17.json"), "--sh-order", "17"});
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("--sh-order"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir_ / "sh17.json"));
}

TEST_F(PrefilterCli, ErrorsAreOneLineAndLeaveNoOutput) {
  test::CommandResult r = run({path("missing.exr"), "-o", path("a.ktx2"), "--lut", path("l.png")});
  EXPECT_EQ(r.code, 1);
  ASSERT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_NE(r.err.find("missing.exr"), std::string::npos);
  // The LUT could be written, the chain's directory does not exist: neither appears.
  r = run({input_, "--lut", path("l.png"), "-o", path("nodir/a.ktx2"), "--size", "8"});
  EXPECT_EQ(r.code, 1);
  EXPECT_EQ(r.err_lines().size(), 1u) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "l.png"));
  // Usage errors exit 2.
  EXPECT_EQ(run({input_}).code, 2);
  EXPECT_EQ(run({input_, "-o", path("a.png")}).code, 2);
  EXPECT_EQ(run({input_, "-o", path("a.ktx2"), "--size", "16", "--levels", "9"}).code, 2);
  EXPECT_EQ(run({input_, "-o", path("a.ktx2"), "--format", "bc6h"}).code, 2);
  for (const auto& e : fs::directory_iterator(dir_))
    EXPECT_TRUE(e.path().filename() == "sky.exr" || e.path().filename().string().rfind("cmd.", 0) == 0) << e.path();
}

TEST_F(PrefilterCli, HelpHasExamples) {
  const test::CommandResult r = run({"--help"});
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("Examples:"), std::string::npos);
  EXPECT_NE(r.out.find("--mapping"), std::string::npos);
}

}  // namespace
