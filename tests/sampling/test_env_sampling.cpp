// Sampling directions from baked tables (env_sampling.h, env_tables.h): chi-square on the sphere for every
// method and grid on a catalogue of small maps built for their extremes (constant, one bright texel, light on the
// pole rows only, ...), pdf consistency, inversion, extremes, file round trips.
#include <envkit/envmap/envmap.h>
#include <envkit/io/color.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/param_factory.h>
#include <envkit/probes.h>
#include <envkit/sampling/distribution_cdf.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "chi2.h"

using namespace envkit;

namespace {

/// A radiance map for the catalogue: grey values on a lat-long, octahedral or HEALPix grid.
struct SphereMap {
  std::string name;
  Kind grid = Kind::LatLong;
  int width = 0, height = 0;
  std::vector<float> radiance;  // W x H grey
  int sub = 2;                  // histogram cells per texel side (tests the distribution inside texels)
  std::size_t samples = 200000;
};

SphereMap make(std::string name, Kind grid, int w, int h, float value = 0.0f) {
  SphereMap m{std::move(name), grid, w, h, std::vector<float>(std::size_t(w) * h, value)};
  return m;
}

std::vector<SphereMap> catalogue() {
  std::vector<SphereMap> maps;
  for (Kind grid : {Kind::LatLong, Kind::Octahedral, Kind::HEALPix}) {
    const std::string g = grid == Kind::LatLong ? "latlong_" : grid == Kind::Octahedral ? "octa_" : "healpix_";
    // HEALPix: N_side 4 (16 x 12); the sun map doubles it to N_side 8.
    const int W = grid == Kind::LatLong ? 32 : 16, H = grid == Kind::HEALPix ? 12 : 16;
    maps.push_back(make(g + "constant", grid, W, H, 1.0f));
    {
      SphereMap m = make(g + "one_bright_texel", grid, W, H, 0.0f);
      m.radiance[5 * W + 7] = 3.0f;
      m.sub = 4;
      maps.push_back(m);
    }
    {
      SphereMap m = make(g + "pole_rows_only", grid, W, H, 0.0f);
      for (int x = 0; x < W; ++x) m.radiance[x] = 1.0f, m.radiance[std::size_t(H - 1) * W + x] = 2.0f;
      maps.push_back(m);
    }
    {
      SphereMap m = make(g + "sun_1e9", grid, W * 2, H * 2, 1e-3f);
      m.radiance[std::size_t(9) * m.width + 11] = 1e6f;
      maps.push_back(m);
    }
    {
      SphereMap m = make(g + "zero_rows", grid, W, H, 0.0f);
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
          if (y < 4 || y > 9) m.radiance[std::size_t(y) * W + x] = float(1 + (x * 7 + y * 3) % 5);
      maps.push_back(m);
    }
  }
  {
    SphereMap m = make("latlong_3x2", Kind::LatLong, 3, 2);
    m.radiance = {1, 2, 3, 4, 0.5f, 6};
    m.sub = 8;
    maps.push_back(m);
  }
  {
    SphereMap m = make("octa_2x2", Kind::Octahedral, 2, 2);
    m.radiance = {1, 5, 0, 2};
    m.sub = 8;
    maps.push_back(m);
  }
  {
    // N_side 1: one texel per base pixel, dark and lit ones in every row of cells.
    SphereMap m = make("healpix_nside1", Kind::HEALPix, 4, 3);
    m.radiance = {1, 5, 0, 2, 0, 3, 7, 0, 4, 0, 0.5f, 6};
    m.sub = 8;
    maps.push_back(m);
  }
  return maps;
}

void PrintTo(const SphereMap& m, std::ostream* os) { *os << m.name; }

std::unique_ptr<Parameterization> grid_param(Kind grid, int w, int h) {
  if (grid == Kind::Octahedral) return std::make_unique<OctahedralMap>(w);
  if (grid == Kind::HEALPix) return std::make_unique<HealpixMap>(w / 4);
  return std::make_unique<LatLongMap>(w, h);
}

// Built directly (not through make_envmap): a 3x2 lat-long is a valid bake grid but not a 2:1 image file.
EnvMap envmap_of(const SphereMap& m) {
  EnvMap env;
  env.image = Image(m.width, m.height, 1);
  env.image.pixels.assign(m.radiance.begin(), m.radiance.end());
  env.param = grid_param(m.grid, m.width, m.height);
  return env;
}

EnvTables bake(const SphereMap& m, bool compensated = false) {
  BakeOptions o;
  o.grid = m.grid;
  o.compensated = compensated;
  return EnvTables::bake(envmap_of(m), o, m.name);
}

const SamplingMethod kMethods[] = {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical};
const int kChi2Tests = int(catalogue().size()) * 3;
const double kAlpha = chi2::sidak_alpha(0.01, kChi2Tests);

std::uint64_t seed_of(const std::string& name, int salt) {
  std::uint64_t h = 1469598103934665603ull;
  for (char c : name) h = (h ^ std::uint8_t(c)) * 1099511628211ull;
  return h + std::uint64_t(salt) * 0x9E3779B97F4A7C15ull;
}

Vec2 random_u(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  return Vec2(U(rng), U(rng));
}

// Every distribution of `baked` and `loaded` draws bit-identical samples (direction, pdf, pdf(direction)) for the
// same n random points.
void expect_same_samples(const EnvTables& baked, const EnvTables& loaded, std::uint64_t seed, int n) {
  for (bool compensated : {false, true})
    for (SamplingMethod method : kMethods) {
      const SphericalDistribution* a = baked.distribution(method, compensated);
      const SphericalDistribution* b = loaded.distribution(method, compensated);
      ASSERT_TRUE(a && b);
      std::mt19937_64 rng(seed);
      for (int i = 0; i < n; ++i) {
        const Vec2 u = random_u(rng);
        const DirectionSample sa = a->sample(u), sb = b->sample(u);
        ASSERT_EQ(std::memcmp(&sa.direction, &sb.direction, sizeof(Vec3)), 0);
        ASSERT_EQ(sa.pdf, sb.pdf);
        ASSERT_EQ(a->pdf(sa.direction), b->pdf(sa.direction));
      }
    }
}

}  // namespace

class EnvSampling : public ::testing::TestWithParam<SphereMap> {};

// Histogram over cells nested in the bake texels (sub x sub per texel, in image coordinates, so cells are NOT
// equal-area inside a lat-long texel), binned with the parameterization's own to_image (independent of the
// sampler's locate()); expected count = N x pdf(cell centre) x exact cell solid angle.
TEST_P(EnvSampling, ChiSquareOnTheSphere) {
  const SphereMap& m = GetParam();
  const EnvTables t = bake(m);
  const auto param = grid_param(m.grid, m.width, m.height);
  const int CW = m.width * m.sub, CH = m.height * m.sub;
  for (SamplingMethod method : kMethods) {
    const SphericalDistribution& d = *t.distribution(method);
    std::vector<double> observed(std::size_t(CW) * CH, 0.0), expected(observed.size(), 0.0);
    for (int cy = 0; cy < CH; ++cy)
      for (int cx = 0; cx < CW; ++cx) {
        const double x0 = double(cx) / m.sub, y0 = double(cy) / m.sub, s = 1.0 / m.sub;
        Vec3 centre;
        param->to_direction(Vec2(x0 + 0.5 * s, y0 + 0.5 * s), centre);
        expected[std::size_t(cy) * CW + cx] =
            double(m.samples) * d.pdf(centre) * param->solid_angle(x0, y0, x0 + s, y0 + s);
      }
    std::mt19937_64 rng(seed_of(m.name, int(method)));
    for (std::size_t n = 0; n < m.samples; ++n) {
      const DirectionSample s = d.sample(random_u(rng));
      const Vec2 p = param->to_image(s.direction);
      const int cx = std::clamp(int(p.x * m.sub), 0, CW - 1), cy = std::clamp(int(p.y * m.sub), 0, CH - 1);
      observed[std::size_t(cy) * CW + cx] += 1.0;
    }
    const chi2::Result r = chi2::test(observed, expected, kAlpha);
    EXPECT_TRUE(r.passed) << m.name << " " << method_name(method) << ": " << r.message;
  }
}

TEST_P(EnvSampling, PdfIntegratesToOne) {
  const SphereMap& m = GetParam();
  const EnvTables t = bake(m);
  // Midpoint quadrature on a fine lat-long grid unrelated to the bake grid (for octahedral maps, too).
  const LatLongMap fine(720, 360);
  for (SamplingMethod method : kMethods) {
    const SphericalDistribution& d = *t.distribution(method);
    double integral = 0.0;
    for (int y = 0; y < 360; ++y) {
      const double omega = fine.solid_angle(0.0, y, 1.0, y + 1.0);
      for (int x = 0; x < 720; ++x) {
        Vec3 dir;
        fine.to_direction(Vec2(x + 0.5, y + 0.5), dir);
        integral += d.pdf(dir) * omega;
      }
    }
    // Exact over the bake texels (pdf is constant per texel).
    double exact = 0.0;
    for (int y = 0; y < m.height; ++y)
      for (int x = 0; x < m.width; ++x) {
        const double pdf_uv = d.distribution().pdf(Vec2((x + 0.5) / m.width, (y + 0.5) / m.height));
        exact += pdf_uv / (double(m.width) * m.height);
      }
    EXPECT_NEAR(exact, 1.0, 1e-6) << m.name << " " << method_name(method);
    // The fine grid straddles texel edges: its error is the pdf's jumps times the straddling area.
    EXPECT_NEAR(integral, 1.0, m.name.find("sun") != std::string::npos ? 0.3 : 0.05)
        << m.name << " " << method_name(method);
  }
}

TEST_P(EnvSampling, SamplePdfMatchesPdfAndInvertRoundTrips) {
  const SphereMap& m = GetParam();
  const EnvTables t = bake(m);
  for (SamplingMethod method : kMethods) {
    const SphericalDistribution& d = *t.distribution(method);
    std::mt19937_64 rng(seed_of(m.name, 10 + int(method)));
    double worst_pdf = 0.0, worst_invert = 0.0;
    for (int n = 0; n < 20000; ++n) {
      const Vec2 u = random_u(rng);
      const DirectionSample s = d.sample(u);
      ASSERT_TRUE(std::isfinite(s.pdf) && s.pdf > 0.0) << m.name;
      ASSERT_NEAR(s.direction.length(), 1.0, 1e-12);
      int x = -1, y = -1;
      d.texel_of(s.direction, x, y);
      EXPECT_EQ(x, s.x);
      EXPECT_EQ(y, s.y);
      worst_pdf = std::max(worst_pdf, std::abs(d.pdf(s.direction) / s.pdf - 1.0));
      if (d.can_invert()) {
        const Vec2 back = d.invert(s.direction);
        worst_invert = std::max({worst_invert, std::abs(back.x - u.x), std::abs(back.y - u.y)});
      }
    }
    EXPECT_LE(worst_pdf, 1e-5) << m.name << " " << method_name(method);
    EXPECT_LE(worst_invert, 1e-4) << m.name << " " << method_name(method);
    EXPECT_EQ(d.can_invert(), method != SamplingMethod::Alias);
  }
}

TEST_P(EnvSampling, ExtremeRandomNumbersAndPoles) {
  const SphereMap& m = GetParam();
  const EnvTables t = bake(m);
  const double hi = 1.0 - std::ldexp(1.0, -24);
  for (SamplingMethod method : kMethods) {
    const SphericalDistribution& d = *t.distribution(method);
    for (Vec2 u : {Vec2(0, 0), Vec2(0, hi), Vec2(hi, 0), Vec2(hi, hi), Vec2(1, 1), Vec2(-1, 2),
                   Vec2(std::nan(""), std::nan(""))}) {
      const DirectionSample s = d.sample(u);
      EXPECT_TRUE(std::isfinite(s.direction.x) && std::isfinite(s.direction.y) && std::isfinite(s.direction.z));
      EXPECT_TRUE(std::isfinite(s.pdf) && s.pdf > 0.0) << m.name << " u=" << u.x << "," << u.y;
      if (d.can_invert()) {
        const Vec2 back = d.invert(s.direction);
        EXPECT_TRUE(std::isfinite(back.x) && std::isfinite(back.y));
      }
    }
    // sin theta = 0: finite (never inf or NaN), and 0 exactly when the pole texel has no light.
    for (Vec3 pole : {Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 0), Vec3(std::nan(""), 0, 0)}) {
      const double p = d.pdf(pole);
      EXPECT_TRUE(std::isfinite(p) && p >= 0.0) << m.name;
    }
  }
}

TEST_P(EnvSampling, LoadedTablesSampleBitIdentically) {
  const SphereMap& m = GetParam();
  const EnvTables baked = bake(m, /*compensated=*/true);
  const auto path = std::filesystem::temp_directory_path() / ("envkit_tables_" + m.name + ".envtbl");
  baked.save(path.string());
  const EnvTables loaded = EnvTables::load(path.string(), baked.source_hash());
  std::filesystem::remove(path);
  EXPECT_TRUE(std::ranges::equal(loaded.importance(), baked.importance()));
  EXPECT_EQ(loaded.descriptor(), baked.descriptor());
  ASSERT_TRUE(baked.source_to_world().has_value());
  EXPECT_EQ(loaded.source_to_world(), baked.source_to_world());  // the frame the directions are in
  EXPECT_EQ(loaded.total_importance(), baked.total_importance());
  expect_same_samples(baked, loaded, seed_of(m.name, 20), 2000);
}

INSTANTIATE_TEST_SUITE_P(Catalogue, EnvSampling, ::testing::ValuesIn(catalogue()),
                         [](const ::testing::TestParamInfo<SphereMap>& param_info) { return param_info.param.name; });

// ---------------------------------------------------------------------------------------------------------------
// Importance

TEST(EnvTablesBake, SelectTablesByName) {
  BakeOptions b;
  select_tables({"pyramid", "compensated"}, b);
  EXPECT_TRUE(b.hierarchical && b.compensated);
  EXPECT_FALSE(b.cdf || b.alias);
  select_tables({"alias", "cdf", "hierarchical"}, b);
  EXPECT_TRUE(b.cdf && b.alias && b.hierarchical);
  EXPECT_FALSE(b.compensated);
  try {
    select_tables({"cdf", "guide"}, b);
    ADD_FAILURE() << "an unknown table name was accepted";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "unknown table 'guide' (cdf, alias, hierarchical, compensated, sun)");
  }
  try {
    select_tables({"compensated"}, b);
    ADD_FAILURE() << "a bake of no method was accepted";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "name at least one of cdf, alias, hierarchical");
  }
}

TEST(EnvTablesBake, TotalImportanceMatchesAnalyticPower) {
  // A uniform grey sky and a sun with closed-form power, rasterized flux-exactly; luminance of grey = grey.
  const LatLongMap map(256, 128);
  const probes::ConstantProbe constant(Vec3(0.5, 0.5, 0.5));
  const probes::SunProbe sun(Vec3(0.3, 0.8, 0.2), 0.01, Vec3(1e5, 1e5, 1e5), Vec3(0.2, 0.2, 0.2));
  for (const probes::Probe* p :
       {static_cast<const probes::Probe*>(&constant), static_cast<const probes::Probe*>(&sun)}) {
    LoadOptions lo;
    lo.kind = Kind::LatLong;
    lo.convention = &envkit::convention("envkit");
    const EnvMap env = make_envmap(probes::rasterize(*p, map), "probe.exr", lo);
    for (ImportanceMode mode : {ImportanceMode::Luminance, ImportanceMode::Average, ImportanceMode::Max}) {
      BakeOptions o;
      o.importance = mode;
      const EnvTables t = EnvTables::bake(env, o);
      EXPECT_NEAR(t.total_importance() / p->total_power().x, 1.0, 1e-5) << p->describe() << importance_name(mode);
    }
    // Through the octahedral grid (resampled with the area filter): power is conserved to 0.1%.
    BakeOptions o;
    o.grid = Kind::Octahedral;
    o.width = o.height = 128;
    EXPECT_NEAR(EnvTables::bake(env, o).total_importance() / p->total_power().x, 1.0, 1e-3) << p->describe();
  }
}

TEST(EnvTablesBake, ImportanceModesFollowTheChannels) {
  Image image(4, 2, 3);
  for (std::size_t i = 0; i < image.texel_count(); ++i) {
    image.pixels[3 * i] = 1.0f;
    image.pixels[3 * i + 1] = 2.0f;
    image.pixels[3 * i + 2] = 6.0f;
  }
  LoadOptions lo;
  lo.kind = Kind::LatLong;
  const EnvMap env = make_envmap(image, "rgb.exr", lo);
  const Vec3 w = luminance_weights("scene_linear");
  const std::pair<ImportanceMode, double> expected[] = {{ImportanceMode::Luminance, w.x * 1 + w.y * 2 + w.z * 6},
                                                        {ImportanceMode::Average, 3.0},
                                                        {ImportanceMode::Max, 6.0}};
  for (const auto& [mode, value] : expected) {
    BakeOptions o;
    o.importance = mode;
    const EnvTables t = EnvTables::bake(env, o);
    for (float v : t.importance()) EXPECT_NEAR(v, value, 1e-5) << importance_name(mode);
    EXPECT_NEAR(t.total_importance(), 4.0 * M_PI * value, 1e-4);
  }
}

TEST(EnvTablesBake, ResolutionConservesPowerAndKeepsSupport) {
  SphereMap m = make("res", Kind::LatLong, 64, 32, 0.0f);
  m.radiance[std::size_t(7) * 64 + 13] = 100.0f;  // one lit texel
  m.radiance[std::size_t(30) * 64 + 2] = 1.0f;
  BakeOptions o;
  o.importance_width = 16;
  o.importance_height = 8;
  const EnvTables full = EnvTables::bake(envmap_of(m), BakeOptions{});
  const EnvTables low = EnvTables::bake(envmap_of(m), o);
  EXPECT_EQ(low.width(), 16);
  EXPECT_EQ(low.height(), 8);
  EXPECT_EQ(low.grid_width(), 64);  // radiance stays on the full grid
  EXPECT_EQ(low.grid_height(), 32);
  EXPECT_NEAR(low.total_importance() / full.total_importance(), 1.0, 1e-3);
  // The coarse pdf is positive wherever there is light.
  const LatLongMap fine(64, 32);
  for (auto [x, y] : {std::pair{13, 7}, std::pair{2, 30}}) {
    Vec3 dir;
    fine.to_direction(Vec2(x + 0.5, y + 0.5), dir);
    EXPECT_GT(low.distribution(SamplingMethod::Cdf)->pdf(dir), 0.0);
  }
  o.importance_width = 128;  // larger than the grid
  o.importance_height = 64;
  EXPECT_THROW(EnvTables::bake(envmap_of(m), o), Error);
}

TEST(EnvTablesBake, ConservativeCoversTheBilinearFootprint) {
  SphereMap m = make("cons", Kind::LatLong, 16, 8, 0.0f);
  m.radiance[std::size_t(3) * 16 + 0] = 5.0f;  // column 0: its footprint wraps to column 15
  BakeOptions o;
  o.conservative = true;
  const EnvTables t = EnvTables::bake(envmap_of(m), o);
  EXPECT_TRUE(t.conservative());
  for (int y = 2; y <= 4; ++y)
    for (int x : {15, 0, 1}) EXPECT_EQ(t.importance()[std::size_t(y) * 16 + x], 5.0f) << x << "," << y;
  EXPECT_EQ(t.importance()[std::size_t(3) * 16 + 2], 0.0f);
  EXPECT_EQ(t.importance()[std::size_t(5) * 16 + 0], 0.0f);
}

TEST(EnvTablesBake, CompensatedSubtractsTheMean) {
  SphereMap m = make("comp", Kind::LatLong, 8, 4, 1.0f);
  for (int x = 0; x < 8; ++x) m.radiance[x] = 9.0f;  // a bright top row
  const EnvTables t = bake(m, true);
  const double mean = t.total_importance() / (4.0 * M_PI);
  const SphericalDistribution& c = *t.distribution(SamplingMethod::Cdf, true);
  const LatLongMap grid(8, 4);
  Vec3 top, bottom;
  grid.to_direction(Vec2(3.5, 0.5), top);
  grid.to_direction(Vec2(3.5, 2.5), bottom);
  EXPECT_EQ(c.pdf(bottom), 0.0);  // 1 < mean
  // pdf is (9 - mean) / integral of max(f - mean, 0) = 1 over the top row.
  const double row = grid.solid_angle(0, 0, 8, 1);
  EXPECT_NEAR(c.pdf(top), 1.0 / row, 1e-5 / row);
  EXPECT_GT(mean, 1.0);
  EXPECT_TRUE(t.warnings().empty());
  // A constant map has no compensated importance: the plain tables are used, with a warning.
  const EnvTables constant = bake(make("flat", Kind::LatLong, 8, 4, 2.0f), true);
  EXPECT_EQ(constant.warnings().size(), 1u);
  EXPECT_EQ(constant.distribution(SamplingMethod::Cdf, true)->pdf(top),
            constant.distribution(SamplingMethod::Cdf)->pdf(top));
}

// direction_in_texel() is public (product sampling calls it): arguments out of range or NaN are clamped into the
// grid and [0, kTexelOffsetMax], never read past the longitude table or give a NaN direction.
TEST(EnvSamplingDirections, DirectionInTexelClampsItsArguments) {
  for (auto [W, H] : {std::pair{32, 16}, std::pair{3000, 1500}}) {
    SphereMap m = make("clamp", Kind::LatLong, W, H, 1.0f);
    const EnvTables t = bake(m);
    const SphericalDistribution& d = *t.distribution(SamplingMethod::Cdf);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const auto same = [](const Vec3& a, const Vec3& b) { return std::memcmp(&a, &b, sizeof(Vec3)) == 0; };
    EXPECT_TRUE(same(d.direction_in_texel(3, 2, -1e-9, 0.5), d.direction_in_texel(3, 2, 0.0, 0.5)));
    EXPECT_TRUE(same(d.direction_in_texel(3, 2, 0.5, -3.0), d.direction_in_texel(3, 2, 0.5, 0.0)));
    EXPECT_TRUE(same(d.direction_in_texel(3, 2, 7.0, 0.5), d.direction_in_texel(3, 2, kTexelOffsetMax, 0.5)));
    EXPECT_TRUE(same(d.direction_in_texel(-5, H + 3, 0.5, 0.5), d.direction_in_texel(0, H - 1, 0.5, 0.5)));
    for (const Vec3& v : {d.direction_in_texel(3, 2, nan, nan), d.direction_in_texel(W, -1, 2.0, nan)}) {
      EXPECT_TRUE(std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z));
      EXPECT_NEAR(v.length(), 1.0, 1e-12);
    }
  }
}

// The lat-long direction of a sample comes from a longitude table and short sin/cos polynomials (no trigonometry
// per sample), with one table step per column from W = 2048 on and several per column below: against the
// closed form in long double (longitude linear in fx, cos theta linear in fy between the row's bounds), for
// small, odd and large widths, every method; direction_in_texel() (product sampling) agrees bit for bit.
TEST(EnvSamplingDirections, MatchTheClosedFormAtEverySize) {
  for (auto [W, H] :
       {std::pair{3, 2}, std::pair{32, 16}, std::pair{1000, 500}, std::pair{2048, 1024}, std::pair{3000, 1500}}) {
    SphereMap m = make("dirs", Kind::LatLong, W, H, 0.0f);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) m.radiance[std::size_t(y) * W + x] = float(1 + (x * 7 + y * 13) % 17);
    const EnvTables t = bake(m);
    for (SamplingMethod method : kMethods) {
      const SphericalDistribution& d = *t.distribution(method);
      std::mt19937_64 rng(seed_of(m.name, W + int(method)));
      double worst = 0.0;
      for (int n = 0; n < 20000; ++n) {
        const Vec2 u = n == 0 ? Vec2(0, 0) : n == 1 ? Vec2(1, 1) : random_u(rng);
        const DirectionSample s = d.sample(u);
        const TexelSample ts = d.distribution().sample_texel(u);
        ASSERT_EQ(s.x, ts.x);
        ASSERT_EQ(s.y, ts.y);
        const Vec3 again = d.direction_in_texel(ts.x, ts.y, ts.fx, ts.fy);
        ASSERT_EQ(std::memcmp(&again, &s.direction, sizeof(Vec3)), 0);
        const long double pi = 3.141592653589793238462643383279502884L;
        const long double lon = pi - 2 * pi * ((ts.x + (long double)ts.fx) / W);
        // cos theta linear in fy between the row's bounds; 1 -+ cos theta from the half angles (no cancellation
        // near the poles).
        const long double t0 = pi * ts.y / H, t1 = pi * (ts.y + 1) / H, fy = ts.fy;
        const long double span = 2 * std::sin((t0 + t1) / 2) * std::sin((t1 - t0) / 2);  // cos t0 - cos t1
        const long double one_minus = 2 * std::sin(t0 / 2) * std::sin(t0 / 2) + fy * span;
        const long double one_plus = 2 * std::cos(t1 / 2) * std::cos(t1 / 2) + (1 - fy) * span;
        const long double cos_theta = (one_plus - one_minus) / 2;
        const long double sin_theta = std::sqrt(one_minus * one_plus);
        const long double ref[3] = {std::sin(lon) * sin_theta, cos_theta, std::cos(lon) * sin_theta};
        const double got[3] = {s.direction.x, s.direction.y, s.direction.z};
        for (int c = 0; c < 3; ++c) worst = std::max(worst, double(std::abs(got[c] - ref[c])));
      }
      EXPECT_LT(worst, 2e-15) << W << "x" << H << " " << method_name(method);
    }
  }
}

TEST(EnvTablesBake, AllBlackMapSamplesUniformlyWithAWarning) {
  const EnvTables t = bake(make("black", Kind::LatLong, 16, 8, 0.0f));
  ASSERT_EQ(t.warnings().size(), 1u);
  EXPECT_EQ(t.warnings()[0].cause, TableWarning::Cause::NoLight);
  EXPECT_NE(t.warnings()[0].message.find("no light"), std::string::npos);
  for (SamplingMethod method : kMethods) {
    const SphericalDistribution& d = *t.distribution(method);
    // Uniform in uv: pdf per steradian is 1 / (W H Omega_texel); it integrates to 1.
    double integral = 0.0;
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 16; ++x) {
        Vec3 dir;
        LatLongMap(16, 8).to_direction(Vec2(x + 0.5, y + 0.5), dir);
        integral += d.pdf(dir) * d.texel_solid_angle(x, y);
      }
    EXPECT_NEAR(integral, 1.0, 1e-6);
    const DirectionSample s = d.sample(Vec2(0.3, 0.7));
    EXPECT_NEAR(s.pdf, d.pdf(s.direction), 1e-12);
  }
}

TEST(EnvTablesBake, ResamplesOtherParameterizationsOntoTheGrid) {
  // A cube map of a sun: baked onto a lat-long grid, the sun's direction gets the highest pdf.
  const probes::SunProbe sun(Vec3(0.2, 0.5, -0.8), 0.05, Vec3(1e4, 1e4, 1e4), Vec3(0.1, 0.1, 0.1));
  ParamSpec spec;
  spec.kind = Kind::CubeMap;
  spec.width = 32;
  spec.height = 192;
  const auto cube = make_parameterization(spec);
  LoadOptions lo;
  lo.kind = Kind::CubeMap;
  const EnvMap env = make_envmap(probes::rasterize(sun, *cube), "cube.exr", lo);
  BakeOptions o;
  const EnvTables t = EnvTables::bake(env, o);
  EXPECT_EQ(t.width(), 2 * t.height());
  EXPECT_NE(t.descriptor().find("resampled_from"), std::string::npos);
  EXPECT_NEAR(t.total_importance() / sun.total_power().x, 1.0, 1e-3);
  const SphericalDistribution& d = *t.distribution(SamplingMethod::Hierarchical);
  EXPECT_GT(d.pdf(sun.direction()), 100.0 * d.pdf(-sun.direction()));
}

// ---------------------------------------------------------------------------------------------------------------
// Table files: corruption, versions, staleness

namespace {

std::vector<char> read_all(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(f), {});
}
void write_all(const std::string& path, const std::vector<char>& bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(bytes.data(), std::streamsize(bytes.size()));
}
std::string load_error(const std::string& path, const std::string& hash = "") {
  try {
    EnvTables::load(path, hash);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(EnvTablesFile, BadFilesAreClearErrors) {
  SphereMap m = make("file", Kind::LatLong, 16, 8, 1.0f);
  m.radiance[20] = 50.0f;
  const EnvTables t = bake(m);
  const std::string path = (std::filesystem::temp_directory_path() / "envkit_bad_tables.envtbl").string();
  t.save(path);
  const std::vector<char> good = read_all(path);
  ASSERT_GT(good.size(), 1024u);

  EXPECT_EQ(load_error(path, t.source_hash()), "");
  EXPECT_NE(load_error(path, std::string(32, '0')).find("stale"), std::string::npos);

  std::vector<char> bytes = good;
  bytes[bytes.size() - 200] ^= 0x10;  // a flipped bit inside the last section
  write_all(path, bytes);
  EXPECT_NE(load_error(path).find("checksum mismatch"), std::string::npos) << load_error(path);

  bytes = good;
  bytes.resize(bytes.size() / 2);
  write_all(path, bytes);
  EXPECT_NE(load_error(path).find("truncated"), std::string::npos) << load_error(path);

  bytes = good;
  bytes[8] = 99;  // version
  write_all(path, bytes);
  EXPECT_NE(load_error(path).find("version 99 is not supported"), std::string::npos) << load_error(path);

  bytes = good;
  bytes[0] = 'X';
  write_all(path, bytes);
  EXPECT_NE(load_error(path).find("not an envkit table file"), std::string::npos);

  write_all(path, {});
  EXPECT_NE(load_error(path).find("not an envkit table file"), std::string::npos);
  for (const std::string& message : {load_error(path), load_error(path + ".missing")})
    EXPECT_EQ(message.rfind(path, 0), 0u) << "the error names the file: " << message;
  std::filesystem::remove(path);
}

// Files of 1 MiB or more are memory-mapped, smaller ones read into memory: both give the baked tables, and a
// truncated large file is the same clear error as a small one.
TEST(EnvTablesFile, LargeAndSmallFilesLoadTheBakedTables) {
  for (const auto& [W, H] : std::vector<std::pair<int, int>>{{16, 8}, {512, 256}}) {
    SphereMap m = make("size" + std::to_string(W), Kind::LatLong, W, H, 1.0f);
    m.radiance[std::size_t(W) * std::size_t(H / 3) + std::size_t(W / 5)] = 500.0f;
    const EnvTables baked = bake(m, /*compensated=*/true);
    const std::string path = (std::filesystem::temp_directory_path() / "envkit_sized_tables.envtbl").string();
    baked.save(path);
    const std::vector<char> good = read_all(path);
    SCOPED_TRACE(std::to_string(good.size()) + " bytes");
    EXPECT_EQ(good.size() >= (std::size_t(1) << 20), W == 512) << "the two files lie on both sides of 1 MiB";
    {
      const EnvTables loaded = EnvTables::load(path, baked.source_hash());
      EXPECT_TRUE(std::ranges::equal(loaded.importance(), baked.importance()));
      expect_same_samples(baked, loaded, seed_of(m.name, 21), 500);
    }
    std::vector<char> bytes = good;
    bytes.resize(bytes.size() - 64);
    write_all(path, bytes);
    EXPECT_NE(load_error(path).find("truncated"), std::string::npos) << load_error(path);
    std::filesystem::remove(path);
  }
}

// texel_of on lat-long grids guesses with a polynomial arctangent and settles the texel against exact edges: it
// must name the texel that the angle formulas name (except within rounding of an edge), and the texel a direction
// was placed in, on grids whose longitude table has one step per column and on grids with several.
TEST(EnvSamplingTexelOf, LatLongTexelIsTheAngleFormulasTexel) {
  std::mt19937_64 rng(77);
  std::normal_distribution<double> gauss;
  std::uniform_real_distribution<double> inside(1e-3, 1.0 - 1e-3);
  for (const auto& [W, H] : std::vector<std::pair<int, int>>{
           {1, 1}, {2, 1}, {3, 2}, {7, 3}, {64, 32}, {1024, 512}, {2048, 1024}, {4096, 7}, {5, 4096}}) {
    SCOPED_TRACE(std::to_string(W) + "x" + std::to_string(H));
    std::vector<float> w(std::size_t(W) * std::size_t(H), 1.0f);
    const SphericalDistribution dist(Kind::LatLong, std::make_shared<CdfDistribution2D>(w.data(), W, H));
    int near_edge = 0;
    for (int i = 0; i < 100000; ++i) {
      Vec3 d(gauss(rng), gauss(rng), gauss(rng));
      if (i < 8)
        d = std::vector<Vec3>{{0, 1, 0},       {0, -1, 0}, {0, 0, -1}, {-1e-300, 0, -1},
                              {1e-300, 0, -1}, {0, 0, 1},  {1, 0, 0},  {-1, 0, 0}}[std::size_t(i)];
      d = d.normalized();
      int x = 0, y = 0;
      dist.texel_of(d, x, y);
      // The angle formulas, and how far the direction is from the nearest texel edge (in texels).
      const double horizontal = std::hypot(d.x, d.z);
      const double u = LatLongMap::u_from_direction(d, horizontal) * W;
      const double v = std::atan2(horizontal, d.y) / kPi * H;
      const int rx = std::clamp(int(u), 0, W - 1), ry = std::clamp(int(v), 0, H - 1);
      const double margin = std::min(std::abs(u - std::round(u)), std::abs(v - std::round(v)));
      if (x == rx && y == ry) continue;
      ++near_edge;
      EXPECT_LT(margin, 1e-9) << "direction (" << d.x << ", " << d.y << ", " << d.z << "): texel (" << x << ", " << y
                              << "), the angles say (" << rx << ", " << ry << ")";
    }
    EXPECT_LT(near_edge, 5);
    // Directions placed inside a texel are found in it.
    std::uniform_int_distribution<int> col(0, W - 1), row(0, H - 1);
    for (int i = 0; i < 20000; ++i) {
      const int tx = col(rng), ty = row(rng);
      const Vec3 d = dist.direction_in_texel(tx, ty, inside(rng), inside(rng));
      int x = 0, y = 0;
      dist.texel_of(d, x, y);
      ASSERT_EQ(x, tx) << "row " << ty;
      ASSERT_EQ(y, ty) << "column " << tx;
    }
  }
}
