// Product tables (lobe_product.h) and the distribution they are made of (distribution_refined.h): the refined warp
// draws texels in proportion to its cell weights times the pyramid below them (chi-square on the standard maps),
// every product table is a normalised density with pdf > 0 wherever the map has light, its samples follow its
// lobe, and tables over one grid share that grid's geometry.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/probes.h>
#include <envkit/sampling/distribution_refined.h>
#include <envkit/sampling/lobe_product.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <functional>
#include <random>
#include <type_traits>

#include "chi2.h"
#include "tables_support.h"

using namespace envkit;
using testmaps::TestMap;
using testmaps::uniform53;

namespace {

std::shared_ptr<const HierarchicalDistribution2D> pyramid_of(const TestMap& m) {
  return std::make_shared<HierarchicalDistribution2D>(m.weights.data(), m.width, m.height);
}

/// The pyramid's own node sums at a level, as cell weights.
std::vector<float> node_cells(const HierarchicalDistribution2D& fine, int level) {
  const int cw = fine.level_width(level), ch = fine.level_height(level);
  std::vector<float> c(std::size_t(cw) * ch);
  for (int j = 0; j < ch; ++j)
    for (int i = 0; i < cw; ++i) c[std::size_t(j) * cw + i] = float(fine.node(level, i, j));
  return c;
}

/// Cell weights that favour some cells over others (a deterministic pattern), positive on every cell.
std::vector<float> uneven_cells(int w, int h) {
  std::vector<float> c(std::size_t(w) * std::size_t(h));
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) c[std::size_t(j) * w + i] = float(1 + ((i * 7 + j * 3) % 5) * ((i + j) % 2 ? 10 : 1));
  return c;
}

/// The map whose ideal probabilities are those a refined distribution over `m` with these cell weights must
/// draw: w(x, y) x cell(c) / node(c), with cells whose node is 0 giving nothing.
TestMap refined_reference(const TestMap& m, const HierarchicalDistribution2D& fine, int level,
                          std::span<const float> cells) {
  TestMap r = m;
  const int cw = fine.level_width(level);
  for (int y = 0; y < m.height; ++y)
    for (int x = 0; x < m.width; ++x) {
      const double node = fine.node(level, x >> level, y >> level);
      const double w = sampling::sanitize_weight(m.weights[std::size_t(y) * m.width + x]);
      r.weights[std::size_t(y) * m.width + x] =
          node > 0.0 ? float(w / node * cells[std::size_t(y >> level) * cw + (x >> level)]) : 0.0f;
    }
  return r;
}

const int kChi2Tests = 2 * int(testmaps::lit_standard_maps().size());
const double kAlpha = chi2::sidak_alpha(0.01, kChi2Tests);

std::uint64_t seed_of(const std::string& name) { return testmaps::seed_of(name, 0x7ef1dull); }

/// The level a test refines at: the middle of the pyramid (so that there are cells and a descent below them).
int middle_level(const HierarchicalDistribution2D& fine) { return fine.levels() / 2; }

}  // namespace

class RefinedMaps : public ::testing::TestWithParam<TestMap> {};

// With the pyramid's own node sums as cell weights the refined warp is the pyramid's distribution.
TEST_P(RefinedMaps, NodeSumsAsCellWeightsGiveTheHierarchicalDistribution) {
  const TestMap& m = GetParam();
  const auto fine = pyramid_of(m);
  for (int level : {0, middle_level(*fine), fine->levels()}) {
    SCOPED_TRACE("level " + std::to_string(level));
    const RefinedDistribution2D d(fine, level, node_cells(*fine, level));
    EXPECT_EQ(testmaps::check_normalised(d), "");
    EXPECT_EQ(testmaps::check_matches_weights(d, m, 1e-5), "");
    EXPECT_EQ(testmaps::check_samples(d, m, 5000, seed_of(m.name) + std::uint64_t(level)), "");
    EXPECT_EQ(testmaps::check_pdf_outside(d), "");
  }
  const int level = middle_level(*fine);
  const chi2::Result r =
      testmaps::chi_square(RefinedDistribution2D(fine, level, node_cells(*fine, level)), m, kAlpha, seed_of(m.name));
  EXPECT_TRUE(r.passed) << m.name << ": " << r.message;
}

// Other cell weights: texel (x, y) of cell c is drawn with probability cell(c) / sum(cells) x w(x, y) / node(c).
TEST_P(RefinedMaps, CellWeightsScaleTheirTexels) {
  const TestMap& m = GetParam();
  const auto fine = pyramid_of(m);
  const int level = middle_level(*fine);
  const std::vector<float> cells = uneven_cells(fine->level_width(level), fine->level_height(level));
  const RefinedDistribution2D d(fine, level, cells);
  const TestMap reference = refined_reference(m, *fine, level, cells);
  const chi2::Result r = testmaps::chi_square(d, reference, kAlpha, seed_of(m.name) + 7);
  EXPECT_TRUE(r.passed) << m.name << ": " << r.message;
  EXPECT_EQ(testmaps::check_matches_weights(d, reference, 1e-5), "");
  EXPECT_EQ(testmaps::check_samples(d, reference, 5000, seed_of(m.name) + 8), "");
  EXPECT_EQ(testmaps::check_normalised(d), "");
  // A sample's pdf is pdf() at its uv bit for bit (one formula on both sides).
  std::mt19937_64 rng(seed_of(m.name) + 9);
  for (int s = 0; s < 2000; ++s) {
    const DistributionSample ds = d.sample(Vec2(uniform53(rng), uniform53(rng)));
    ASSERT_EQ(d.pdf(ds.uv), ds.pdf) << ds.x << "," << ds.y;
  }
}

// Maps with light only: the refined warp has no uniform fallback (its cells need light).
INSTANTIATE_TEST_SUITE_P(Maps, RefinedMaps, ::testing::ValuesIn(testmaps::lit_standard_maps()), testmaps::MapName());

TEST(RefinedDistribution2D, RefusesBadInput) {
  const TestMap m = testmaps::find_map("Constant8x4");
  const auto fine = pyramid_of(m);
  const std::vector<float> one(1, 1.0f);
  EXPECT_THROW(RefinedDistribution2D(nullptr, 0, one), Error);
  EXPECT_THROW(RefinedDistribution2D(fine, -1, one), Error);
  EXPECT_THROW(RefinedDistribution2D(fine, fine->levels() + 1, one), Error);
  EXPECT_THROW(RefinedDistribution2D(fine, 0, one), Error);  // a cell per texel expected
  const std::vector<float> zero(std::size_t(fine->level_width(1)) * fine->level_height(1), 0.0f);
  EXPECT_THROW(RefinedDistribution2D(fine, 1, zero), Error);  // no cell with a positive weight
  // Built at load from the pyramid it refines: table files cannot hold it.
  static_assert(!std::is_base_of_v<StoredDistribution2D, RefinedDistribution2D>);
}

namespace {

using test::bake;

const std::vector<Lobe> kLobes = {{Lobe::Shape::Cosine, 1.0}, {Lobe::Shape::Ggx, 0.05}, {Lobe::Shape::Ggx, 0.3}};

/// Axes of every octant and the poles.
std::vector<Vec3> test_axes() {
  return {Vec3(0, 1, 0),
          Vec3(0, -1, 0),
          Vec3(1, 0, 0),
          Vec3(0.3, 0.4, -0.866).normalized(),
          Vec3(-0.5, -0.2, 0.6).normalized(),
          Vec3(-0.7, 0.7, -0.1).normalized()};
}

struct GridCase {
  const char* name;
  std::function<std::unique_ptr<Parameterization>()> param;
  Kind grid;
};

std::vector<GridCase> grids() {
  return {{"latlong", [] { return std::make_unique<LatLongMap>(128, 64); }, Kind::LatLong},
          {"octahedral", [] { return std::make_unique<OctahedralMap>(64); }, Kind::Octahedral},
          {"healpix", [] { return std::make_unique<HealpixMap>(16); }, Kind::HEALPix}};
}

}  // namespace

// Every table is a density on the sphere: its texel densities integrate to 1, a sample's pdf is pdf(direction),
// and pdf > 0 on every texel with light (the floor), whatever the lobe, the axis and the grid.
TEST(LobeProductTables, EveryTableIsANormalisedDensityPositiveWhereTheMapHasLight) {
  const probes::SunProbe probe(Vec3(0.4, 0.5, -0.77).normalized(), 3.0 * kPi / 180.0, Vec3(2e3, 1.8e3, 1.5e3),
                               Vec3(0.3, 0.4, 0.6));
  for (const GridCase& g : grids()) {
    SCOPED_TRACE(g.name);
    const EnvTables tables = bake(probe, g.param(), g.grid);
    const SphericalDistribution& env = *tables.distribution(SamplingMethod::Hierarchical);
    const LobeProductTables product(env, kLobes);
    const std::span<const float> importance = tables.importance();
    const int W = env.width(), H = env.height();
    std::mt19937_64 rng(11);
    for (int l = 0; l < int(kLobes.size()); ++l)
      for (const Vec3& axis : test_axes()) {
        const SphericalDistribution& d = product.table(l, axis).distribution;
        double total = 0.0;
        for (int y = 0; y < H; ++y)
          for (int x = 0; x < W; ++x) {
            const double p = d.texel_pdf(x, y);
            total += p * d.texel_solid_angle(x, y);
            if (importance[std::size_t(y) * W + x] > 0.0f) {
              ASSERT_GT(p, 0.0) << l << " " << x << "," << y;
            }
          }
        EXPECT_NEAR(total, 1.0, 1e-5) << "lobe " << l;
        for (int s = 0; s < 200; ++s) {
          const DirectionSample ds = d.sample(Vec2(uniform53(rng), uniform53(rng)));
          ASSERT_GT(ds.pdf, 0.0);
          EXPECT_NEAR(d.pdf(ds.direction), ds.pdf, 1e-9 * ds.pdf) << "lobe " << l;
        }
      }
  }
}

// The tables do not depend on the thread count that built them: the same bits under one thread and under many.
TEST(LobeProductTables, TablesDoNotDependOnTheThreadCount) {
  const probes::SunProbe probe(Vec3(0.2, 0.6, 0.7).normalized(), 2.0 * kPi / 180.0, Vec3(5e3), Vec3(0.4));
  const EnvTables tables = bake(probe, std::make_unique<LatLongMap>(128, 64), Kind::LatLong);
  const SphericalDistribution& env = *tables.distribution(SamplingMethod::Hierarchical);
  const LobeProductTables many(env, kLobes);
  std::unique_ptr<LobeProductTables> one;
  {
    tbb::global_control serial(tbb::global_control::max_allowed_parallelism, 1);
    one = std::make_unique<LobeProductTables>(env, kLobes);
  }
  for (int l = 0; l < int(kLobes.size()); ++l)
    for (const Vec3& axis : test_axes())
      for (int y = 0; y < env.height(); ++y)
        for (int x = 0; x < env.width(); ++x)
          ASSERT_EQ(one->table(l, axis).distribution.texel_pdf(x, y), many.table(l, axis).distribution.texel_pdf(x, y));
}

// Texels with a 1e-50 share of the map's light each: every table still draws them with a positive density.
TEST(LobeProductTables, TheFloorReachesTheDimmestLight) {
  LatLongMap grid(64, 32);
  const probes::TexelProbe probe(grid, 40, 5, Vec3(1e30), Vec3(1e-20));
  const EnvTables tables = bake(probe, std::make_unique<LatLongMap>(64, 32), Kind::LatLong);
  const SphericalDistribution& env = *tables.distribution(SamplingMethod::Hierarchical);
  const LobeProductTables product(env, kLobes);
  for (int l = 0; l < int(kLobes.size()); ++l)
    for (const Vec3& axis : test_axes()) {
      const SphericalDistribution& d = product.table(l, axis).distribution;
      for (int y = 0; y < env.height(); ++y)
        for (int x = 0; x < env.width(); ++x) ASSERT_GT(d.texel_pdf(x, y), 0.0) << l << " " << x << "," << y;
    }
}

// On a constant map a table draws directions by its lobe (and the floor): the cosine table puts most samples above
// the axis's horizon, weighted towards the axis; the narrow GGX table puts most of them near its axis. The table is the
// one of the axis's bin, for axes anywhere.
TEST(LobeProductTables, SamplesFollowTheLobeAroundTheAxis) {
  const EnvTables tables =
      bake(probes::ConstantProbe(Vec3(1.0)), std::make_unique<LatLongMap>(256, 128), Kind::LatLong);
  const LobeProductTables product(*tables.distribution(SamplingMethod::Hierarchical), kLobes);
  std::mt19937_64 rng(5);
  for (const Vec3& axis : test_axes()) {
    SCOPED_TRACE(axis.x);
    const int n = 20000;
    double above = 0.0, mean_cos = 0.0, near = 0.0;
    const SphericalDistribution& cosine = product.table(0, axis).distribution;
    const SphericalDistribution& narrow = product.table(1, axis).distribution;
    for (int s = 0; s < n; ++s) {
      const Vec3 d = cosine.sample(Vec2(uniform53(rng), uniform53(rng))).direction;
      above += (d ^ axis) > 0.0;
      mean_cos += std::max(0.0, d ^ axis);
      const Vec3 g = narrow.sample(Vec2(uniform53(rng), uniform53(rng))).direction;
      near += (g ^ axis) > std::cos(25.0 * kPi / 180.0);
    }
    EXPECT_GT(above / n, 0.85);
    // Above the horizon the mean cosine lies between a uniform hemisphere's (1/2) and a cosine-weighted one's
    // (2/3): the table's lobe is the cosine widened by its bin's and cells' radii.
    EXPECT_GT(mean_cos / above, 0.55);
    EXPECT_LT(mean_cos / above, 2.0 / 3.0);
    EXPECT_GT(near / n, 0.7);  // 25 degrees: the bin, the cells and the lobe together
  }
}

// A table's mean_importance is the sky its lobe sees: the map's radiance for every lobe and axis under a constant map;
// under a sky that brightens upwards (L = 0.1 + 10 max(y, 0)), the radiance at a narrow lobe's axis and the upper
// hemisphere's mean weighted by the cosine's (widened) lobe.
TEST(LobeProductTables, MeanImportanceIsTheSkyALobeSees) {
  const EnvTables constant =
      bake(probes::ConstantProbe(Vec3(2.0)), std::make_unique<LatLongMap>(128, 64), Kind::LatLong);
  const LobeProductTables flat(*constant.distribution(SamplingMethod::Hierarchical), kLobes);
  // The importance of a grey 2.0 (its luminance), within the float rounding of the pyramid's sums.
  for (int l = 0; l < int(kLobes.size()); ++l)
    for (const Vec3& axis : test_axes()) EXPECT_NEAR(flat.table(l, axis).mean_importance, 2.0, 1e-6);

  const EnvTables sky =
      bake(probes::GradientProbe(Vec3(0.1), Vec3(10.0)), std::make_unique<LatLongMap>(128, 64), Kind::LatLong);
  const LobeProductTables product(*sky.distribution(SamplingMethod::Hierarchical), kLobes);
  const Vec3 up(0, 1, 0), down(0, -1, 0);
  const double cosine_up = product.table(0, up).mean_importance, cosine_down = product.table(0, down).mean_importance;
  const double narrow_up = product.table(1, up).mean_importance, narrow_down = product.table(1, down).mean_importance;
  // The narrow lobe: the zenith's and the nadir's radiance, within 5% (its table's lobe is widened over the bin).
  EXPECT_NEAR(narrow_up, 10.1, 0.05 * 10.1);
  EXPECT_NEAR(narrow_down, 0.1, 0.05 * 0.1);
  // The cosine up: between the uniform upper hemisphere's mean (0.1 + 10 x 1/2) and the cosine-weighted one's
  // (0.1 + 10 x 2/3), its widened lobe being flatter than the cosine; down, it sees a little of the upper sky.
  EXPECT_GT(cosine_up, 5.1);
  EXPECT_LT(cosine_up, 0.1 + 10.0 * 2.0 / 3.0);
  EXPECT_GT(cosine_down, 0.1);
  EXPECT_LT(cosine_down, 0.25);
}

TEST(LobeProductTables, LobeValues) {
  // The GGX reflection lobe is the density of directions reflected by visible normals at normal incidence: it
  // integrates to 1 over the sphere; the cosine lobe integrates to pi.
  for (const Lobe lobe : {Lobe{Lobe::Shape::Ggx, 0.1}, Lobe{Lobe::Shape::Ggx, 0.5}, Lobe{Lobe::Shape::Cosine, 1.0}}) {
    const int n = 400000;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) sum += lobe.value(1.0 - 2.0 * (i + 0.5) / n);
    const double integral = sum * kTwoPi * 2.0 / n;
    EXPECT_NEAR(integral, lobe.shape == Lobe::Shape::Cosine ? kPi : 1.0, 2e-3) << lobe.alpha;
  }
  const Lobe ggx{Lobe::Shape::Ggx, 0.05};
  EXPECT_EQ(ggx.value(-1.0), 0.0);
  EXPECT_EQ(ggx.value(std::nan("")), 0.0);
  EXPECT_GT(ggx.value(1.0), ggx.value(0.99));
  EXPECT_EQ((Lobe{Lobe::Shape::Cosine, 1.0}.value(-0.5)), 0.0);
}

TEST(LobeProductTables, RefusesBadInput) {
  const EnvTables tables = bake(probes::ConstantProbe(Vec3(1.0)), std::make_unique<LatLongMap>(64, 32), Kind::LatLong);
  EXPECT_THROW(LobeProductTables(*tables.distribution(SamplingMethod::Cdf), kLobes), Error);
  EXPECT_THROW(LobeProductTables(*tables.distribution(SamplingMethod::Hierarchical), {}), Error);
  EXPECT_THROW(LobeProductTables(*tables.distribution(SamplingMethod::Hierarchical), {{Lobe::Shape::Ggx, 0.0}}), Error);
  const LobeProductTables product(*tables.distribution(SamplingMethod::Hierarchical), kLobes);
  EXPECT_EQ(product.find(kLobes[2]), 2);
  EXPECT_EQ(product.find(Lobe{Lobe::Shape::Ggx, 0.7}), -1);
  // A zero or NaN axis gets a table (bin 0), never an out-of-range one.
  EXPECT_GT(product.table(0, Vec3(0, 0, 0)).distribution.sample(Vec2(0.5, 0.5)).pdf, 0.0);
  EXPECT_GT(product.table(1, Vec3(std::nan(""), 0, 1)).distribution.sample(Vec2(0.5, 0.5)).pdf, 0.0);
}

// A distribution built on another's grid samples exactly as one built on its own.
TEST(SphericalDistribution, SharedGridSamplesAsItsOwn) {
  const EnvTables tables =
      bake(probes::GradientProbe(Vec3(0.2), Vec3(1.0)), std::make_unique<LatLongMap>(64, 32), Kind::LatLong);
  const SphericalDistribution& own = *tables.distribution(SamplingMethod::Cdf);
  const SphericalDistribution shared(*tables.distribution(SamplingMethod::Hierarchical), own.distribution_ptr());
  std::mt19937_64 rng(3);
  for (int s = 0; s < 1000; ++s) {
    const Vec2 u(uniform53(rng), uniform53(rng));
    const DirectionSample a = own.sample(u), b = shared.sample(u);
    EXPECT_EQ(a.direction.x, b.direction.x);
    EXPECT_EQ(a.direction.y, b.direction.y);
    EXPECT_EQ(a.direction.z, b.direction.z);
    EXPECT_EQ(a.pdf, b.pdf);
  }
  const TestMap small = testmaps::find_map("Constant8x4");
  EXPECT_THROW(SphericalDistribution(own, pyramid_of(small)), Error);  // another size
}

namespace {

bool same_sample(const DirectionSample& a, const DirectionSample& b) {
  return a.direction.x == b.direction.x && a.direction.y == b.direction.y && a.direction.z == b.direction.z &&
         a.pdf == b.pdf && a.x == b.x && a.y == b.y;
}

}  // namespace

// A refined draw is the hierarchical pick over its cell weights, then the fine pyramid's pick_below from the chosen
// cell, bit for bit (offsets and density), and its texel density is the composed density: the cells' storage in a
// RefinedCellStore (several tables side by side, levels top first) changes no value.
TEST_P(RefinedMaps, AStoresTablesDrawAsTheCellPyramidAndThePyramidBelowIt) {
  const TestMap& m = GetParam();
  const auto fine = pyramid_of(m);
  const int level = middle_level(*fine);
  const int cw = fine->level_width(level), ch = fine->level_height(level);
  std::vector<std::vector<float>> weights = {uneven_cells(cw, ch), node_cells(*fine, level), uneven_cells(cw, ch)};
  for (std::size_t c = 0; c < weights[2].size(); ++c) weights[2][c] = weights[2][c] * float(1 + c % 3) + 0.5f;
  auto store = std::make_shared<RefinedCellStore>(fine, level, weights.size());
  for (std::size_t t = weights.size(); t-- > 0;) store->build(t, weights[t]);  // any order
  EXPECT_EQ(store->table_bytes() % 64, 0u);
  std::mt19937_64 rng(seed_of(m.name) + 21);
  for (std::size_t t = 0; t < weights.size(); ++t) {
    const RefinedDistribution2D d(store, t);
    // The cell pyramid as HierarchicalDistribution2D builds it, with the cells that cannot be drawn set to 0.
    std::vector<float> supported(weights[t]);
    for (int j = 0; j < ch; ++j)
      for (int i = 0; i < cw; ++i)
        if (!(fine->node(level, i, j) > 0.0)) supported[std::size_t(j) * cw + i] = 0.0f;
    const HierarchicalDistribution2D cells(supported.data(), cw, ch);
    for (int s = 0; s < 3000; ++s) {
      const Vec2 u(uniform53(rng), uniform53(rng));
      const TexelSample cell = cells.pick(u);
      const TexelSample below = fine->pick_below(level, cell.x, cell.y, Vec2(cell.fx, cell.fy));
      const TexelSample got = d.pick(u);
      ASSERT_EQ(got.x, below.x);
      ASSERT_EQ(got.y, below.y);
      ASSERT_EQ(got.fx, below.fx);
      ASSERT_EQ(got.fy, below.fy);
      const double cell_probability = cell.pdf * (1.0 / (double(cw) * double(ch)));  // the cell's density x its area
      ASSERT_EQ(got.pdf, below.pdf * cell_probability);
      ASSERT_EQ(d.texel_pdf(got.x, got.y), got.pdf);
    }
    // The standalone constructor builds the same table.
    const RefinedDistribution2D alone(fine, level, weights[t]);
    for (int s = 0; s < 200; ++s) {
      const Vec2 u(uniform53(rng), uniform53(rng));
      const TexelSample a = alone.pick(u), b = d.pick(u);
      ASSERT_TRUE(a.x == b.x && a.y == b.y && a.fx == b.fx && a.fy == b.fy && a.pdf == b.pdf);
    }
    EXPECT_EQ(testmaps::check_normalised(d), "");
  }
  EXPECT_THROW(store->build(weights.size(), weights[0]), Error);  // no such table
  EXPECT_THROW(RefinedDistribution2D(store, weights.size()), Error);
}

// The draws of a shading point taken together (the descents of a group interleaved, each sample from its own
// table of a mixture) are the draws taken one by one, bit for bit, on every grid, in groups of any size; and a
// draw's pdf is texel_pdf() of its texel.
TEST(LobeProductTables, DrawsTakenTogetherAreTheDrawsTakenOneByOne) {
  const probes::SunProbe probe(Vec3(0.4, 0.5, -0.77).normalized(), 2.0 * kPi / 180.0, Vec3(4e3), Vec3(0.3, 0.4, 0.6));
  for (const GridCase& g : grids()) {
    SCOPED_TRACE(g.name);
    const EnvTables tables = bake(probe, g.param(), g.grid);
    const LobeProductTables product(*tables.distribution(SamplingMethod::Hierarchical), kLobes);
    std::mt19937_64 rng(17);
    for (const Vec3& axis : test_axes())
      for (std::size_t n : {std::size_t(1), std::size_t(2), std::size_t(4), std::size_t(7), std::size_t(130)}) {
        std::vector<const SphericalDistribution*> from(n);
        std::vector<Vec2> u(n);
        for (std::size_t k = 0; k < n; ++k) {
          from[k] = &product.table(int(rng() % kLobes.size()), axis).distribution;
          u[k] = Vec2(uniform53(rng), uniform53(rng));
        }
        std::vector<DirectionSample> together(n);
        SphericalDistribution::sample_each(from, u, together);
        for (std::size_t k = 0; k < n; ++k) {
          const DirectionSample one = from[k]->sample(u[k]);
          ASSERT_TRUE(same_sample(together[k], one)) << n << " " << k;
          ASSERT_EQ(from[k]->texel_pdf(one.x, one.y), one.pdf);
        }
        // One table's batch (its sample_texels) likewise.
        std::vector<DirectionSample> batch(n);
        from[0]->sample(u, batch);
        for (std::size_t k = 0; k < n; ++k) ASSERT_TRUE(same_sample(batch[k], from[0]->sample(u[k]))) << n << " " << k;
      }
    const SphericalDistribution* one[1] = {&product.table(0, Vec3(0, 1, 0)).distribution};
    DirectionSample out[2];
    const Vec2 u[2] = {Vec2(0.5, 0.5), Vec2(0.5, 0.5)};
    EXPECT_THROW(SphericalDistribution::sample_each(one, u, out), Error);  // sizes differ
  }
}
