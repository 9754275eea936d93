// The measured material (MERL binary BRDFs, renderer/src/material_measured.cpp and merl.h): files written from
// analytic BRDFs (a Lambertian of albedo 0.5 and a white GGX conductor of alpha 0.3) load back into materials that
// agree with them; the tabulated sampler's pdf is the density it draws (chi-square) and integrates to at most 1;
// the furnace; no NaN at grazing or below the horizon; each kind of bad file is refused with one message; a
// measured Lambertian sphere renders as the diffuse one.
#include <chi2.h>
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/render/integrator.h>
#include <envkit/render/material.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "../../renderer/src/merl.h"  // private: the format's cells, shared with the writer below
#include "bsdf_support.h"
#include "render_support.h"

namespace envkit::render {
namespace {

using namespace bsdf_test;
using testmaps::uniform53;
namespace fs = std::filesystem;

constexpr double kLambertAlbedo = 0.5;
constexpr double kGgxAlpha = 0.3;

/// This process's directory for the MERL files the tests write (35 MB each), removed when the tests end.
fs::path work_dir_path() { return fs::temp_directory_path() / ("envkit_measured_" + std::to_string(::getpid())); }

fs::path work_dir() {
  static const fs::path dir = [] {
    fs::create_directories(work_dir_path());
    return work_dir_path();
  }();
  return dir;
}

class RemoveWorkDir final : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(work_dir_path(), ec);
  }
};
[[maybe_unused]] ::testing::Environment* const kRemoveWorkDir = ::testing::AddGlobalTestEnvironment(new RemoveWorkDir);

/// Writes a MERL file: the header `dims`, then `values` as doubles, then `extra` bytes.
void write_raw(const fs::path& file, const std::int32_t (&dims)[3], const std::vector<double>& values,
               std::size_t extra = 0) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(dims), sizeof dims);
  out.write(reinterpret_cast<const char*>(values.data()), std::streamsize(values.size() * sizeof(double)));
  out.write(std::string(extra, '\0').data(), std::streamsize(extra));
}

constexpr std::int32_t kDims[3] = {merl::kThetaHalfCells, merl::kThetaDiffCells, merl::kPhiDiffCells};

/// The stored values of a BRDF f (RGB, 1/sr) sampled at each cell's centre. A cell whose centre directions leave the
/// upper hemisphere holds -1 (missing) when `missing_outside`, else f there too.
std::vector<double> merl_values(const std::function<Vec3(const Vec3&, const Vec3&)>& f, bool missing_outside) {
  std::vector<double> v(3 * merl::kCells);
  for (int th = 0; th < merl::kThetaHalfCells; ++th)
    for (int td = 0; td < merl::kThetaDiffCells; ++td)
      for (int pd = 0; pd < merl::kPhiDiffCells; ++pd) {
        merl::HalfDiff hd{merl::theta_half_of_cell(th), merl::theta_diff_of_cell(td), merl::phi_diff_of_cell(pd)};
        Vec3 wo, wi;
        merl::directions(hd, wo, wi);
        const bool missing = missing_outside && !(wo.z > 0.0 && wi.z > 0.0);
        const Vec3 value = missing ? Vec3(0.0) : f(wo, wi);
        const std::size_t i = merl::cell_index(th, td, pd);
        for (int c = 0; c < 3; ++c) v[std::size_t(c) * merl::kCells + i] = missing ? -1.0 : value[c] / merl::kScale[c];
      }
  return v;
}

const std::unique_ptr<Material>& ggx_reference() {
  static const std::unique_ptr<Material> m = make_conductor(Vec3(0.0), Vec3(1.0), kGgxAlpha);  // F = 1
  return m;
}

fs::path lambert_file() {
  static const fs::path p = [] {
    const fs::path file = work_dir() / "lambert.binary";
    write_raw(file, kDims, merl_values([](const Vec3&, const Vec3&) { return Vec3(kLambertAlbedo / kPi); }, false));
    return file;
  }();
  return p;
}

fs::path ggx_file() {
  static const fs::path p = [] {
    const fs::path file = work_dir() / "ggx.binary";
    write_raw(file, kDims,
              merl_values([](const Vec3& wo, const Vec3& wi) { return ggx_reference()->eval(wo, wi) / wi.z; }, true));
    return file;
  }();
  return p;
}

const Material& lambert() {
  static const std::unique_ptr<Material> m = make_measured(lambert_file().string());
  return *m;
}
const Material& ggx() {
  static const std::unique_ptr<Material> m = make_measured(ggx_file().string());
  return *m;
}

double mean3(const Vec3& v) { return (v.x + v.y + v.z) / 3.0; }

// ---------------------------------------------------------------------------------------------------------------
// The format's coordinates.

TEST(MerlCoordinates, DirectionsAndHalfDiffAreInverse) {
  std::mt19937_64 rng(3);
  for (int i = 0; i < 10000; ++i) {
    merl::HalfDiff hd{uniform53(rng) * kPi / 2, uniform53(rng) * kPi / 2, uniform53(rng) * kPi}, back;
    Vec3 wo, wi;
    merl::directions(hd, wo, wi);
    ASSERT_TRUE(merl::half_diff(wo, wi, back));
    EXPECT_NEAR(back.theta_half, hd.theta_half, 1e-6);
    EXPECT_NEAR(back.theta_diff, hd.theta_diff, 1e-6);
    if (hd.theta_diff > 1e-3 && hd.theta_diff < kPi / 2 - 1e-3) {
      const double d = std::abs(back.phi_diff - hd.phi_diff);
      EXPECT_LT(std::min(d, kPi - d), 1e-6);
    }
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Agreement with the analytic BRDFs the files were written from.

TEST(MeasuredMaterial, LambertianFileEvaluatesToAlbedoOverPi) {
  const Material& m = lambert();
  EXPECT_STREQ(m.name(), "measured");
  std::mt19937_64 rng(5);
  for (int i = 0; i < 20000; ++i) {
    const Vec3 wo = direction_zphi(uniform53(rng), kTwoPi * uniform53(rng));
    const Vec3 wi = direction_zphi(uniform53(rng), kTwoPi * uniform53(rng));
    if (wo.z <= 0.0 || wi.z <= 0.0) continue;
    const Vec3 f = m.eval(wo, wi);
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(f[c], kLambertAlbedo / kPi * wi.z, 1e-6 * wi.z) << wo << " " << wi;
  }
}

// Trilinear interpolation between the cell centres: within 3% of the analytic lobe wherever it is above 1% of its
// peak and both directions are within 70 degrees of the normal (near grazing the cells next to the horizon are
// missing, written black); exact at cell centres.
TEST(MeasuredMaterial, GgxFileAgreesWithTheConductorAwayFromGrazing) {
  const Material& m = ggx();
  const Material& ref = *ggx_reference();
  const double peak = ref.eval(Vec3(0, 0, 1), Vec3(0, 0, 1)).x;
  std::mt19937_64 rng(6);
  double worst = 0.0;
  const double zmin = std::cos(70.0 * kPi / 180.0);
  int checked = 0;
  for (int i = 0; i < 200000; ++i) {
    const Vec3 wo = direction_zphi(zmin + (1 - zmin) * uniform53(rng), kTwoPi * uniform53(rng));
    const Vec3 wi = direction_zphi(zmin + (1 - zmin) * uniform53(rng), kTwoPi * uniform53(rng));
    const double want = ref.eval(wo, wi).x / wi.z;
    if (want < 0.01 * peak) continue;
    ++checked;
    const Vec3 got = m.eval(wo, wi) / wi.z;
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(got[c] / want - 1.0));
  }
  EXPECT_GT(checked, 10000);
  EXPECT_LT(worst, 0.03);
  std::printf("GGX alpha %.2f from a MERL file: worst relative error %.4f over %d pairs\n", kGgxAlpha, worst, checked);
  // At a cell's centre the table holds the exact value (float storage).
  for (int th : {5, 20, 40}) {
    merl::HalfDiff hd{merl::theta_half_of_cell(th), merl::theta_diff_of_cell(30), merl::phi_diff_of_cell(50)};
    Vec3 wo, wi;
    merl::directions(hd, wo, wi);
    const double want = ref.eval(wo, wi).x;
    EXPECT_NEAR(m.eval(wo, wi).y, want, 1e-6 * want) << th;
  }
}

TEST(MeasuredMaterial, LobeAlphasComeFromTheData) {
  EXPECT_EQ(lambert().widest_lobe_alpha(), 1.0);
  EXPECT_EQ(lambert().narrowest_lobe_alpha(), 1.0);
  std::printf("GGX alpha %.2f: narrowest %.3f, widest %.3f\n", kGgxAlpha, ggx().narrowest_lobe_alpha(),
              ggx().widest_lobe_alpha());
  EXPECT_NEAR(ggx().narrowest_lobe_alpha(), kGgxAlpha, 0.1);
  EXPECT_NEAR(ggx().widest_lobe_alpha(), kGgxAlpha, 0.1);
  EXPECT_LE(ggx().narrowest_lobe_alpha(), ggx().widest_lobe_alpha());
}

// ---------------------------------------------------------------------------------------------------------------
// The sampler.

struct Named {
  const char* name;
  const Material& (*material)();
};
void PrintTo(const Named& n, std::ostream* os) { *os << n.name; }
class MeasuredSampling : public ::testing::TestWithParam<Named> {};

constexpr double kWoAngles[] = {0.0, 30.0, 60.0, 85.0};
/// The pdf is piecewise constant over half-vector cells: 8 x 8 pieces per grid cell refined 4 times resolve its steps
/// to 1/128 of a grid cell, enough for expected counts of a few hundred.
constexpr int kPdfQuadratureDepth = 4;

// Histogram of sample() over the sphere grid against N x the integral of pdf() over each cell; the pdf integrates
// to the share of sample() calls that return a direction, never above 1.
TEST_P(MeasuredSampling, SampleMatchesPdf) {
  const Material& m = GetParam().material();
  const SphereGrid grid;
  constexpr std::size_t n = 400000;
  for (double theta_o : kWoAngles) {
    SCOPED_TRACE("wo theta = " + std::to_string(theta_o));
    const Vec3 wo = wo_at(theta_o);
    std::mt19937_64 rng(77 + std::uint64_t(theta_o));
    std::vector<double> observed(std::size_t(grid.cells()), 0.0);
    std::size_t ok = 0;
    for (std::size_t i = 0; i < n; ++i) {
      BsdfSample s;
      if (!m.sample(wo, Vec2(uniform53(rng), uniform53(rng)), uniform53(rng), s)) continue;
      ASSERT_TRUE(s.pdf > 0.0 && finite3(s.wi) && s.wi.z > 0.0);
      ++ok;
      observed[std::size_t(grid.cell_of(s.wi))] += 1.0;
    }
    const std::vector<double> mass = integrate_cells(
        grid, [&](const Vec3& wi) { return m.pdf(wo, wi); }, 1e-9, 8, kPdfQuadratureDepth);
    double total = 0.0;
    for (double x : mass) total += x;
    const double accepted = double(ok) / double(n);
    EXPECT_LE(total, 1.0 + 1e-4);
    EXPECT_NEAR(total, accepted, 4.0 * std::sqrt(accepted * (1.0 - accepted) / double(n)) + 2e-4);
    std::vector<double> expected(mass.size());
    for (std::size_t c = 0; c < mass.size(); ++c) expected[c] = mass[c] * double(n);
    const chi2::Result r = chi2::test(observed, expected, chi2::sidak_alpha(0.01, 2 * 4));
    EXPECT_TRUE(r.passed) << r.message;
  }
}

// sample() returns eval() and pdf() of its direction, so f_cos / pdf is the same either way (what MIS needs).
TEST_P(MeasuredSampling, SampleAgreesWithEvalAndPdf) {
  const Material& m = GetParam().material();
  std::mt19937_64 rng(99);
  for (double theta_o : {0.0, 10.0, 45.0, 80.0, 89.9}) {
    const Vec3 wo = wo_at(theta_o, 77.0);
    for (int i = 0; i < 20000; ++i) {
      BsdfSample s;
      if (!m.sample(wo, Vec2(uniform53(rng), uniform53(rng)), uniform53(rng), s)) continue;
      const double p = m.pdf(wo, s.wi);
      ASSERT_GT(p, 0.0);
      ASSERT_NEAR(s.pdf, p, 1e-9 * p);
      const Vec3 f = m.eval(wo, s.wi);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(s.f_cos[c], f[c], 1e-12 + 1e-9 * f[c]);
    }
  }
}

// The furnace: the mean of f_cos / pdf over sample() is the directional albedo, 0.5 for the Lambertian at every
// theta_o, and the conductor's albedo (by quadrature of the analytic lobe) within the interpolation's 2% for GGX.
TEST_P(MeasuredSampling, FurnaceEstimateIsTheAlbedo) {
  const Material& m = GetParam().material();
  const bool is_lambert = std::string(GetParam().name) == "Lambertian";
  for (double theta_o : {0.0, 30.0, 60.0}) {
    SCOPED_TRACE("wo theta = " + std::to_string(theta_o));
    const Vec3 wo = wo_at(theta_o);
    std::mt19937_64 rng(11 + std::uint64_t(theta_o));
    constexpr int n = 200000;
    double sum = 0.0, sum2 = 0.0;
    for (int i = 0; i < n; ++i) {
      BsdfSample s;
      double w = 0.0;
      if (m.sample(wo, Vec2(uniform53(rng), uniform53(rng)), uniform53(rng), s)) w = mean3(s.f_cos) / s.pdf;
      sum += w;
      sum2 += w * w;
    }
    const double mean = sum / n, sigma = std::sqrt(std::max(0.0, sum2 / n - mean * mean) / n);
    double want = kLambertAlbedo, tolerance = 4.0 * sigma;
    if (!is_lambert) {
      const std::vector<double> cells = integrate_cells(
          SphereGrid{}, [&](const Vec3& wi) { return ggx_reference()->eval(wo, wi).x; }, 1e-7);
      want = 0.0;
      for (double x : cells) want += x;
      tolerance += 0.02 * want;
    }
    std::printf("%s theta_o %.0f: furnace %.5f +- %.5f, albedo %.5f\n", GetParam().name, theta_o, mean, sigma, want);
    EXPECT_NEAR(mean, want, tolerance);
  }
}

TEST_P(MeasuredSampling, NoNanAtGrazingOrBelowTheHorizon) {
  const Material& m = GetParam().material();
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Vec3> dirs = {Vec3(0, 0, 1),      Vec3(1, 0, 0),      Vec3(0, 0, -1),     Vec3(1, 0, 1e-300),
                                  Vec3(1, 0, 1e-12),  Vec3(-1, 0, 1e-12), Vec3(0, 1, -1e-12), Vec3(0.6, 0, 0.8),
                                  Vec3(-0.6, 0, 0.8), Vec3(0, 0, 0),      Vec3(nan, 0, 1),    Vec3(0, inf, 1),
                                  Vec3(1, 0, 5e-324)};
  const double us[] = {0.0, 1e-300, 0.5, kOneMinusEpsilon, 1.0, nan};
  for (const Vec3& wo : dirs) {
    for (const Vec3& wi : dirs) {
      const Vec3 f = m.eval(wo, wi);
      const double p = m.pdf(wo, wi);
      ASSERT_TRUE(finite3(f) && f.x >= 0 && f.y >= 0 && f.z >= 0) << "eval " << wo << " " << wi;
      ASSERT_TRUE(std::isfinite(p) && p >= 0.0) << "pdf " << wo << " " << wi;
      if (!(wo.z > 0.0) || !(wi.z > 0.0)) {
        ASSERT_TRUE(p == 0.0 && f == Vec3(0.0));
      }
    }
    for (double a : us)
      for (double b : us) {
        BsdfSample s;
        if (m.sample(wo, Vec2(a, b), 0.5, s)) {
          ASSERT_TRUE(wo.z > 0.0);
          ASSERT_TRUE(finite3(s.wi) && finite3(s.f_cos) && std::isfinite(s.pdf) && s.pdf > 0.0 && s.wi.z > 0.0);
        }
      }
  }
}

const Material& lambert_ref() { return lambert(); }
const Material& ggx_ref() { return ggx(); }
INSTANTIATE_TEST_SUITE_P(Files, MeasuredSampling,
                         ::testing::Values(Named{"Lambertian", &lambert_ref}, Named{"Ggx", &ggx_ref}),
                         [](const ::testing::TestParamInfo<Named>& i) { return std::string(i.param.name); });

// ---------------------------------------------------------------------------------------------------------------
// Bad files: one message naming the file and the problem.

std::string load_error(const fs::path& file) {
  try {
    make_measured(file.string());
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(MeasuredFile, BadFilesAreRefusedWithOneLine) {
  const std::vector<double> ok(3 * merl::kCells, 100.0);
  const fs::path d = work_dir();
  struct Bad {
    const char* file;
    std::function<void(const fs::path&)> make;
    const char* says;
  };
  std::vector<double> with_nan = ok, negative(3 * merl::kCells, -1.0);
  with_nan[merl::kCells + 12345] = std::numeric_limits<double>::quiet_NaN();
  const std::int32_t wrong_dims[3] = {90, 90, 360};
  const std::vector<Bad> cases = {
      {"missing.binary", [](const fs::path&) {}, "no such file"},
      {"header.binary", [](const fs::path& p) { std::ofstream(p) << "MERL"; }, "shorter than the 12-byte header"},
      {"dims.binary", [&](const fs::path& p) { write_raw(p, wrong_dims, ok); }, "header dimensions 90 x 90 x 360"},
      {"truncated.binary",
       [&](const fs::path& p) { write_raw(p, kDims, std::vector<double>(ok.begin(), ok.begin() + 1000)); },
       "truncated: 8012 bytes"},
      {"long.binary", [&](const fs::path& p) { write_raw(p, kDims, ok, 8); }, "more than the 34992012"},
      {"nan.binary", [&](const fs::path& p) { write_raw(p, kDims, with_nan); }, "NaN value at cell 12345 of the green"},
      {"negative.binary", [&](const fs::path& p) { write_raw(p, kDims, negative); }, "no positive value"},
  };
  for (const Bad& b : cases) {
    const fs::path p = d / b.file;
    b.make(p);
    const std::string message = load_error(p);
    EXPECT_NE(message.find(p.string()), std::string::npos) << message;
    EXPECT_NE(message.find(b.says), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    std::error_code ec;
    fs::remove(p, ec);
  }
}

// The scene format: "file" is relative to the scene file, "scale" multiplies f per channel; a bad file's message names
// the scene, the line and the field before the file's own problem.
TEST(MeasuredScene, FileIsRelativeToTheSceneAndScaleMultiplies) {
  lambert_file();  // written into work_dir()
  const std::string scene_file = (work_dir() / "scene.json").string();
  const auto scene_text = [](const std::string& material) {
    return R"({"camera": {"position": [0, 0, -5], "look_at": [0, 0, 0], "resolution": [4, 2]},
"environment": {"probe": "constant"},
"materials": {"m": )" +
           material + R"(},
"shapes": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}]})";
  };
  const LoadedScene loaded = load_scene_text(
      scene_text(R"({"type": "measured", "file": "lambert.binary", "scale": [1, 0.5, 2]})"), scene_file);
  const Material& m = loaded.scene->material(loaded.scene->find_material("m"));
  const Vec3 f = m.eval(Vec3(0, 0, 1), Vec3(0, 0, 1));
  EXPECT_NEAR(f.x, kLambertAlbedo / kPi, 1e-6);
  EXPECT_NEAR(f.y, 0.5 * kLambertAlbedo / kPi, 1e-6);
  EXPECT_NEAR(f.z, 2.0 * kLambertAlbedo / kPi, 1e-6);
  try {
    load_scene_text(scene_text(R"({"type": "measured", "file": "nowhere.binary"})"), scene_file);
    ADD_FAILURE() << "a missing MERL file was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("scene.json:3: materials.m.file: MERL BRDF file '"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("nowhere.binary' does not exist"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Rendering: a sphere of the measured Lambertian renders as the diffuse sphere of the same albedo.

TEST(MeasuredRender, LambertianSphereMatchesTheDiffuseSphere) {
  LatLongMap grid(64, 32);
  LoadOptions load;
  load.kind = Kind::LatLong;
  const EnvMap map = make_envmap(
      probes::rasterize(probes::SunProbe(Vec3(0.3, 1.0, -0.4), 0.15, Vec3(40.0), Vec3(0.3, 0.5, 0.9)), grid), "sun",
      load);
  BakeOptions bake;
  bake.compensated = true;
  const auto tables = std::make_shared<EnvTables>(EnvTables::bake(map, bake));
  const EnvironmentLight light(map, tables);
  const Camera camera(Vec3(0, 0, -4), Vec3(0, 0, 0), Vec3(0, 1, 0), 30.0, 16, 16);
  RenderOptions ro;
  ro.spp = 64;
  const auto render = [&](std::unique_ptr<Material> material, Strategy strategy) {
    Scene scene;
    scene.add_sphere(Vec3(0, 0, 0), 1.0, scene.add_material("m", std::move(material)));
    scene.commit();
    const Integrator integrator(
        scene, light, envkit::test::strategy_options(strategy, SamplingMethod::Hierarchical, Heuristic::Power, 1, 1));
    Film film = render_image(camera, integrator, ro);
    EXPECT_EQ(integrator.nonfinite_count(), 0u);
    return film;
  };
  for (Strategy strategy : {Strategy::Bsdf, Strategy::Mis, Strategy::ProductMis}) {
    SCOPED_TRACE(strategy_name(strategy));
    const Film a = render(make_diffuse(Vec3(kLambertAlbedo)), strategy);
    const Film b = render(make_measured(lambert_file().string()), strategy);
    double sum_a = 0.0, sum_b = 0.0, var = 0.0;
    for (int y = 0; y < a.height(); ++y)
      for (int x = 0; x < a.width(); ++x)
        for (int c = 0; c < 3; ++c) {
          const double ma = a.mean(x, y)[c], mb = b.mean(x, y)[c];
          const double v = a.variance(x, y)[c] + b.variance(x, y)[c];
          EXPECT_NEAR(ma, mb, 5.0 * std::sqrt(v) + 1e-9) << x << "," << y << " channel " << c;
          sum_a += ma;
          sum_b += mb;
          var += v;
        }
    EXPECT_NEAR(sum_a, sum_b, 4.0 * std::sqrt(var) + 1e-9);
  }
}

}  // namespace
}  // namespace envkit::render
