// envbake, envsample and envinfo on table files, run as a user runs them.
#include <OpenImageIO/imageio.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "cli_support.h"

namespace fs = std::filesystem;
using envkit::test::CommandResult;

namespace {

/// envsample's CSV (header u0,u1,x,y,z,pdf,texel_x,texel_y): the header line and the rows, 8 numbers each.
struct SampleCsv {
  std::string header;
  std::vector<std::array<double, 8>> rows;
};

SampleCsv read_sample_csv(const std::string& path) {
  SampleCsv csv;
  std::istringstream in(envkit::test::read_text(path));
  std::getline(in, csv.header);
  for (std::string line; std::getline(in, line);) {
    std::array<double, 8> v{};
    char comma;
    std::istringstream ls(line);
    ls >> v[0];
    for (int k = 1; k < 8; ++k) ls >> comma >> v[k];
    csv.rows.push_back(v);
  }
  return csv;
}

class TablesCli : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() / ("envkit_tables_cli_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(root_);
    fs::create_directories(root_ / "w");
    // A sun over a sky: 64 x 32, written as an envkit lat-long.
    const envkit::probes::SunProbe sun(envkit::Vec3(0.3, 0.6, 0.5), 0.08, envkit::Vec3(5e3, 4e3, 3e3),
                                       envkit::Vec3(0.2, 0.3, 0.5));
    envkit::WriteOptions wo;
    wo.metadata["envkit:parameterization"] = "latlong";
    envkit::write_image(path("sky.exr"), envkit::probes::rasterize(sun, envkit::LatLongMap(64, 32)), wo);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  std::string path(const std::string& name) const { return (root_ / "w" / name).string(); }
  std::set<std::string> listing() const {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(root_ / "w")) names.insert(e.path().filename().string());
    return names;
  }
  CommandResult tool(const std::string& name, const std::vector<std::string>& args) const {
    return envkit::test::run_tool(name, args, root_);
  }
  CommandResult ok(const std::string& name, const std::vector<std::string>& args) const {
    CommandResult r = tool(name, args);
    EXPECT_EQ(r.code, 0) << name << " failed: " << r.err;
    return r;
  }
  /// Exit 1, one stderr line naming `file` and containing `problem`, and no new files.
  void fails(const std::string& name, const std::vector<std::string>& args, const std::string& file,
             const std::string& problem) const {
    const std::set<std::string> before = listing();
    const CommandResult r = tool(name, args);
    EXPECT_EQ(r.code, 1) << r.err;
    const auto lines = r.err_lines();
    ASSERT_EQ(lines.size(), 1u) << r.err;
    EXPECT_NE(lines[0].find(file), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find(problem), std::string::npos) << lines[0];
    EXPECT_EQ(listing(), before) << "no output or temporary file may appear";
  }

  fs::path root_;
};

}  // namespace

TEST_F(TablesCli, BakeDescribeSampleEndToEnd) {
  const CommandResult bake = ok("envbake", {path("sky.exr"), "-o", path("sky.envtbl"), "--tables",
                                            "cdf,alias,hierarchical,compensated", "--json", "-q"});
  const auto j = nlohmann::json::parse(bake.out);
  EXPECT_EQ(j["grid"], "latlong");
  EXPECT_EQ(j["width"], 64);
  EXPECT_EQ(j["source"]["hash"], envkit::file_content_hash({path("sky.exr")}));
  EXPECT_EQ(j["methods"].size(), 3u);
  EXPECT_EQ(j["compensated_methods"].size(), 3u);

  const CommandResult info = ok("envinfo", {path("sky.envtbl")});
  EXPECT_NE(info.out.find("latlong 64 x 32"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("hierarchical-compensated"), std::string::npos);

  // CSV: the pdf column is the tables' pdf of the direction column; directions are unit vectors.
  ok("envsample", {path("sky.envtbl"), "-n", "500", "--method", "cdf", "-o", path("s.csv"), "-q"});
  const envkit::EnvTables t = envkit::EnvTables::load(path("sky.envtbl"));
  const SampleCsv csv = read_sample_csv(path("s.csv"));
  EXPECT_EQ(csv.header, "u0,u1,x,y,z,pdf,texel_x,texel_y");
  for (const auto& v : csv.rows) {
    const envkit::Vec3 dir(v[2], v[3], v[4]);
    EXPECT_NEAR(dir.length(), 1.0, 1e-12);
    EXPECT_NEAR(v[5] / t.distribution(envkit::SamplingMethod::Cdf)->pdf(dir), 1.0, 1e-9);
  }
  EXPECT_EQ(csv.rows.size(), 500u);

  // Same seed, same samples; the picture formats write.
  ok("envsample", {path("sky.envtbl"), "-n", "500", "--method", "cdf", "-o", path("t.csv"), "-q"});
  EXPECT_EQ(envkit::test::read_text(path("s.csv")), envkit::test::read_text(path("t.csv")));
  ok("envsample",
     {path("sky.envtbl"), "-n", "2000", "--method", "alias", "--sequence", "random", "-o", path("s.png"), "-q"});
  ok("envsample", {path("sky.envtbl"), "-n", "200000", "--compensated", "-o", path("d.exr"), "--width", "64", "-q"});
  EXPECT_TRUE(fs::exists(path("s.png")));
  // The density picture converges to the pdf: compare their integrals over the sun's cap region.
  const envkit::Image density = envkit::read_image(path("d.exr"));
  double r_sum = 0.0, g_sum = 0.0;
  for (std::size_t i = 0; i < density.texel_count(); ++i) {
    r_sum += density.pixels[3 * i];
    g_sum += density.pixels[3 * i + 1];
  }
  EXPECT_NEAR(r_sum / g_sum, 1.0, 0.05);

  ok("envinfo", {path("sky.envtbl"), "--export-exr", path("x")});
  for (const char* name :
       {"x_importance.exr", "x_probability.exr", "x_marginal.exr", "x_conditional.exr", "x_level0.exr", "x_level6.exr"})
    EXPECT_TRUE(fs::exists(path(name))) << name;
  const envkit::Image marginal = envkit::read_image(path("x_marginal.exr"));
  EXPECT_EQ(marginal.width, 1);
  EXPECT_EQ(marginal.height, 32);
  double total = 0.0;
  for (float p : marginal.pixels) total += p;
  EXPECT_NEAR(total, 1.0, 1e-5);
  const envkit::Image top = envkit::read_image(path("x_level6.exr"));
  EXPECT_EQ(top.width * top.height, 1);
  EXPECT_NEAR(top.pixels[0], 1.0, 1e-6);
}

TEST_F(TablesCli, ResolutionAndOctahedral) {
  const CommandResult r = ok("envbake", {path("sky.exr"), "-o", path("low.envtbl"), "--resolution", "16x8", "--json"});
  EXPECT_EQ(nlohmann::json::parse(r.out)["width"], 16);
  const CommandResult o =
      ok("envbake", {path("sky.exr"), "-o", path("oct.envtbl"), "--param", "octahedral", "--size", "32", "--json"});
  const auto j = nlohmann::json::parse(o.out);
  EXPECT_EQ(j["grid"], "octahedral");
  EXPECT_EQ(j["width"], 32);
  EXPECT_TRUE(j["bake"].contains("resampled_from"));
}

TEST_F(TablesCli, HealpixTablesEndToEnd) {
  ok("envconvert", {path("sky.exr"), "-o", path("hp.exr"), "--to", "healpix", "--size", "8", "-q"});
  const CommandResult bake = ok("envbake", {path("hp.exr"), "-o", path("hp.envtbl"), "--param", "healpix", "--json"});
  const auto j = nlohmann::json::parse(bake.out);
  EXPECT_EQ(j["grid"], "healpix");
  EXPECT_EQ(j["width"], 32);
  EXPECT_EQ(j["height"], 24);
  EXPECT_FALSE(j["bake"].contains("resampled_from")) << "a HEALPix map is baked on its own texels";

  const CommandResult info = ok("envinfo", {path("hp.envtbl")});
  EXPECT_NE(info.out.find("healpix 32 x 24 (N_side 8"), std::string::npos) << info.out;

  // CSV: pdf column = the tables' pdf of the direction, the texel columns = the texel the direction lies in.
  ok("envsample", {path("hp.envtbl"), "-n", "500", "--method", "hierarchical", "-o", path("s.csv"), "-q"});
  const envkit::EnvTables t = envkit::EnvTables::load(path("hp.envtbl"));
  const envkit::SphericalDistribution& d = *t.distribution(envkit::SamplingMethod::Hierarchical);
  const SampleCsv csv = read_sample_csv(path("s.csv"));
  for (const auto& v : csv.rows) {
    const envkit::Vec3 dir(v[2], v[3], v[4]);
    EXPECT_NEAR(v[5] / d.pdf(dir), 1.0, 1e-9);
    int x = -1, y = -1;
    d.texel_of(dir, x, y);
    EXPECT_EQ(x, int(v[6]));
    EXPECT_EQ(y, int(v[7]));
  }
  EXPECT_EQ(csv.rows.size(), 500u);
  // The density picture converges to the pdf.
  ok("envsample", {path("hp.envtbl"), "-n", "200000", "-o", path("d.exr"), "--width", "64", "-q"});
  const envkit::Image density = envkit::read_image(path("d.exr"));
  double r_sum = 0.0, g_sum = 0.0;
  for (std::size_t i = 0; i < density.texel_count(); ++i) {
    r_sum += density.pixels[3 * i];
    g_sum += density.pixels[3 * i + 1];
  }
  EXPECT_NEAR(r_sum / g_sum, 1.0, 0.05);

  // A lat-long source is resampled onto N_side = --size; --resolution must be a HEALPix size too.
  const CommandResult r = ok("envbake", {path("sky.exr"), "-o", path("r.envtbl"), "--param", "healpix", "--size", "4",
                                         "--resolution", "8x6", "--json"});
  const auto k = nlohmann::json::parse(r.out);
  EXPECT_EQ(k["grid_width"], 16);
  EXPECT_EQ(k["width"], 8);
  EXPECT_TRUE(k["bake"].contains("resampled_from"));
}

TEST_F(TablesCli, HealpixBadSizesAreRefused) {
  // A usage error: the importance resolution of a HEALPix table is 4M x 3M.
  const CommandResult r =
      tool("envbake", {path("sky.exr"), "-o", path("z.envtbl"), "--param", "healpix", "--resolution", "16x16"});
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("4M x 3M"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("z.envtbl")));
  // An image tagged HEALPix whose size no HEALPix image has: one line naming the file.
  envkit::Image bad(40, 20, 3);
  envkit::WriteOptions wo;
  wo.metadata["envkit:parameterization"] = "healpix";
  envkit::write_image(path("bad_hp.exr"), bad, wo);
  fails("envbake", {path("bad_hp.exr"), "-o", path("bad.envtbl"), "--param", "healpix"}, "bad_hp.exr",
        "4 N_side x 3 N_side");
}

TEST_F(TablesCli, BadInputsAreOneLineErrorsWithoutOutput) {
  ok("envbake", {path("sky.exr"), "-o", path("sky.envtbl"), "-q"});
  // Corrupt, truncated and old-version tables.
  std::string bytes = envkit::test::read_text(path("sky.envtbl"));
  const auto write = [&](const std::string& name, const std::string& content) {
    std::ofstream(path(name), std::ios::binary) << content;
  };
  std::string corrupt = bytes;
  corrupt[corrupt.size() - 100] ^= 1;
  write("corrupt.envtbl", corrupt);
  write("truncated.envtbl", bytes.substr(0, bytes.size() / 3));
  std::string old = bytes;
  old[8] = 0;
  write("old.envtbl", old);
  write("notes.envtbl", "hello, not a table\n");
  fails("envsample", {path("corrupt.envtbl"), "-o", path("a.csv")}, "corrupt.envtbl", "checksum mismatch");
  fails("envsample", {path("truncated.envtbl"), "-o", path("a.csv")}, "truncated.envtbl", "truncated");
  fails("envinfo", {path("old.envtbl")}, "old.envtbl", "version 0 is not supported");
  fails("envsample", {path("notes.envtbl"), "-o", path("a.png")}, "notes.envtbl", "not an envkit table file");
  fails("envsample", {path("missing.envtbl"), "-o", path("a.png")}, "missing.envtbl", "cannot open");
  // A table without the requested method.
  ok("envbake", {path("sky.exr"), "-o", path("cdf.envtbl"), "--tables", "cdf", "-q"});
  fails("envsample", {path("cdf.envtbl"), "--method", "alias", "-o", path("a.csv")}, "cdf.envtbl",
        "has no alias table");
  // Non-finite input pixels: same policy as envconvert (error unless --fix-nonfinite).
  envkit::Image nan_map = envkit::read_image(path("sky.exr"));
  nan_map.pixels[7] = std::nanf("");
  {  // write_image refuses NaN: write through OIIO directly
    OIIO::ImageSpec spec(nan_map.width, nan_map.height, nan_map.channels, OIIO::TypeDesc::FLOAT);
    spec.attribute("envkit:parameterization", "latlong");
    auto out = OIIO::ImageOutput::create(path("nan.exr"));
    ASSERT_TRUE(out && out->open(path("nan.exr"), spec) &&
                out->write_image(OIIO::TypeDesc::FLOAT, nan_map.pixels.data()) && out->close());
  }
  fails("envbake", {path("nan.exr"), "-o", path("nan.envtbl")}, "nan.exr", "NaN");
  ok("envbake", {path("nan.exr"), "-o", path("nan.envtbl"), "--fix-nonfinite", "zero", "-q"});
  // Never overwrite the input; usage errors exit 2.
  fails("envbake", {path("sky.exr"), "-o", path("sky.exr")}, "sky.exr", "input");
  EXPECT_EQ(tool("envbake", {path("sky.exr"), "-o", path("z.envtbl"), "--tables", "fast"}).code, 2);
  EXPECT_EQ(tool("envbake", {path("sky.exr"), "-o", path("z.envtbl"), "--resolution", "0x4"}).code, 2);
  EXPECT_EQ(tool("envsample", {path("sky.envtbl"), "-o", path("z.txt")}).code, 2);
  EXPECT_FALSE(fs::exists(path("z.envtbl")));
}

TEST_F(TablesCli, AllBlackMapBakesUniformTablesWithAWarning) {
  envkit::Image black(32, 16, 3);
  envkit::WriteOptions wo;
  wo.metadata["envkit:parameterization"] = "latlong";
  envkit::write_image(path("black.exr"), black, wo);
  const CommandResult r = ok("envbake", {path("black.exr"), "-o", path("black.envtbl"), "-q"});
  EXPECT_NE(r.err.find("warning"), std::string::npos);
  EXPECT_NE(r.err.find("no light"), std::string::npos);
  const envkit::EnvTables t = envkit::EnvTables::load(path("black.envtbl"));
  const envkit::DirectionSample s =
      t.distribution(envkit::SamplingMethod::Hierarchical)->sample(envkit::Vec2(0.5, 0.5));
  EXPECT_NEAR(s.pdf, t.distribution(envkit::SamplingMethod::Hierarchical)->pdf(s.direction), 1e-12);
}

// Values no bake produces, written behind valid checksums (the file is resealed after the patch): the loader's value
// validation must refuse them with one line naming the file, before any sampler runs into NaN, negative or zero
// nodes, broken CDFs or alias coins that disagree with the weights. envsample draws with each method.
TEST_F(TablesCli, HostileValuesBehindValidChecksumsAreRefused) {
  ok("envbake", {path("sky.exr"), "-o", path("sky.envtbl"), "--tables", "cdf,alias,hierarchical", "-q"});
  std::vector<std::byte> baked;
  {
    std::ifstream f(path("sky.envtbl"), std::ios::binary);
    const std::vector<char> bytes((std::istreambuf_iterator<char>(f)), {});
    baked.resize(bytes.size());
    std::memcpy(baked.data(), bytes.data(), bytes.size());
  }
  const auto section = [&](const std::string& name) {
    for (const envkit::TableFileSection& s : envkit::table_file_sections(baked))
      if (s.name == name) return s;
    ADD_FAILURE() << "no section " << name;
    return envkit::TableFileSection{};
  };
  struct Case {
    std::string method, section;
    std::size_t align, shift;  // the patched float: at (size / 2) rounded down to `align`, plus `shift`
    float value;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<Case> cases = {
      {"hierarchical", "hierarchical", 4, 0, nan},
      {"hierarchical", "hierarchical", 4, 0, -1.0f},
      {"hierarchical", "hierarchical", 4, 0, 0.0f},
      {"hierarchical", "hierarchical", 4, 0, 1e30f},
      {"cdf", "cdf", 4, 0, nan},
      {"cdf", "cdf", 4, 0, -0.25f},
      {"cdf", "cdf", 4, 0, 2.0f},
      {"alias", "alias", 16, 8, 0.0f},   // a texel's weight
      {"alias", "alias", 16, 0, nan},    // a texel's coin
      {"alias", "alias", 16, 0, 0.75f},  // a coin outside [-1/2, 1/2]
      {"cdf", "importance", 4, 0, -5.0f},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.section + " value " + std::to_string(c.value));
    std::vector<std::byte> file = baked;
    const envkit::TableFileSection s = section(c.section);
    const std::size_t at = s.offset + (s.size / 2) / c.align * c.align + c.shift;
    std::memcpy(file.data() + at, &c.value, sizeof(float));
    envkit::reseal_table_file(file);
    {
      std::ofstream f(path("patched.envtbl"), std::ios::binary | std::ios::trunc);
      f.write(reinterpret_cast<const char*>(file.data()), std::streamsize(file.size()));
    }
    fails("envsample", {path("patched.envtbl"), "-o", path("s.csv"), "--method", c.method, "-n", "64"},
          path("patched.envtbl"), "invalid");
  }
  // The untouched file, resealed, still loads: the validation refuses values, not valid tables.
  std::vector<std::byte> same = baked;
  envkit::reseal_table_file(same);
  EXPECT_EQ(same, baked);
  ok("envsample", {path("sky.envtbl"), "-o", path("ok.csv"), "--method", "alias", "-n", "64", "-q"});
}

// File names are bytes: a name that is not UTF-8 must not make a JSON report fail (nor leave an output behind).
// The JSON shows U+FFFD for the invalid byte.
TEST_F(TablesCli, NonUtf8FileNamesInJsonReports) {
  const std::string name = path("sky\xff.exr");
  fs::copy_file(path("sky.exr"), name);
  const CommandResult bake = ok("envbake", {name, "-o", path("t\xfe.envtbl"), "--json", "-q"});
  const nlohmann::json b = nlohmann::json::parse(bake.out);
  EXPECT_EQ(b.at("source").at("path").get<std::string>(), path("sky\xEF\xBF\xBD.exr"));
  const CommandResult info = ok("envinfo", {name, "--json"});
  EXPECT_EQ(nlohmann::json::parse(info.out).at("file").get<std::string>(), path("sky\xEF\xBF\xBD.exr"));
  const CommandResult tables = ok("envinfo", {path("t\xfe.envtbl"), "--json"});
  EXPECT_EQ(nlohmann::json::parse(tables.out).at("file").get<std::string>(), path("t\xEF\xBF\xBD.envtbl"));
  const CommandResult diff = ok("envdiff", {name, name, "--json"});
  EXPECT_TRUE(nlohmann::json::accept(diff.out)) << diff.out;
  const CommandResult probe = ok("envprobe", {"constant", "-o", path("p\xff.exr"), "--size", "16x8", "--json"});
  EXPECT_EQ(nlohmann::json::parse(probe.out).at("output").get<std::string>(), path("p\xEF\xBF\xBD.exr"));
  EXPECT_TRUE(fs::exists(path("p\xff.exr")));
  const CommandResult merge = ok("envmerge", {name, "-o", path("m\xff.exr"), "--size", "8", "--json", "-q"});
  EXPECT_EQ(nlohmann::json::parse(merge.out).at("output").get<std::string>(), path("m\xEF\xBF\xBD.exr"));
  EXPECT_EQ(nlohmann::json::parse(merge.out).at("captures").at(0).at("file").get<std::string>(),
            path("sky\xEF\xBF\xBD.exr"));
}
