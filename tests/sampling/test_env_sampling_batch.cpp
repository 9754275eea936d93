// The batched sample (SphericalDistribution::sample over a span, Distribution2D::sample_texels): bit for bit the
// scalar sample(u) of every element, for every method on lat-long, octahedral and HEALPix grids, at lengths that
// are empty, single, shorter than, equal to and not a multiple of the group size, and at u on the edges.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/sampling/distribution_alias.h>
#include <envkit/sampling/distribution_cdf.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <envkit/sampling/distribution_refined.h>
#include <envkit/sampling/distribution_sparse.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

using namespace envkit;

namespace {

const SamplingMethod kMethods[] = {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical};

struct Grid {
  std::string name;
  Kind kind;
  int width, height;
};

/// Lat-long below and at 2048 columns (the longitude table's sub-steps and one step per column), an odd size (the
/// pyramid's partial nodes), octahedral and HEALPix.
const Grid kGrids[] = {{"latlong_64x32", Kind::LatLong, 64, 32},
                       {"latlong_2048x1024", Kind::LatLong, 2048, 1024},
                       {"latlong_37x19", Kind::LatLong, 37, 19},
                       {"octahedral_64", Kind::Octahedral, 64, 64},
                       {"healpix_16", Kind::HEALPix, 64, 48}};

/// A sky with a bright sun and some black rows: both parts of the two-sided CDFs, alias coins of every kind, zero
/// nodes in the pyramid.
EnvMap sky_map(const Grid& g) {
  EnvMap env;
  env.image = Image(g.width, g.height, 1);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (int y = 0; y < g.height; ++y)
    for (int x = 0; x < g.width; ++x) env.image.pixels[std::size_t(y) * g.width + x] = y % 7 == 3 ? 0.0f : U(rng);
  env.image.pixels[std::size_t(g.height / 3) * g.width + g.width / 5] = 1e7f;
  if (g.kind == Kind::Octahedral)
    env.param = std::make_unique<OctahedralMap>(g.width);
  else if (g.kind == Kind::HEALPix)
    env.param = std::make_unique<HealpixMap>(g.width / 4);
  else
    env.param = std::make_unique<LatLongMap>(g.width, g.height);
  return env;
}

/// Random u plus the edges: 0, 1 - 2^-24, the largest double below 1, 1, outside [0, 1) and NaN.
std::vector<Vec2> test_u(std::size_t n) {
  const double edges[] = {0.0, 0.5, 1.0 - std::ldexp(1.0, -24), kOneMinusEpsilon, 1.0, -0.25, 2.0, std::nan("")};
  std::vector<Vec2> u;
  for (double a : edges)
    for (double b : edges) u.emplace_back(a, b);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  while (u.size() < n) u.emplace_back(U(rng), U(rng));
  u.resize(n);
  return u;
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

/// batched == scalar, bit for bit, for every length in `lengths` (prefixes of u).
void expect_batch_matches_scalar(const SphericalDistribution& d, const std::vector<Vec2>& u, const std::string& what) {
  std::vector<DirectionSample> scalar(u.size());
  for (std::size_t k = 0; k < u.size(); ++k) scalar[k] = d.sample(u[k]);
  const std::size_t group = sampling::kSampleGroup;
  for (std::size_t n : {std::size_t(0), std::size_t(1), group - 1, group, group + 1, 3 * group + 7, u.size()}) {
    // Start anywhere: also at an offset that is not a multiple of the group.
    for (std::size_t start : {std::size_t(0), std::size_t(5)}) {
      if (start + n > u.size()) continue;
      std::vector<DirectionSample> batch(n);
      d.sample(std::span<const Vec2>(u.data() + start, n), batch);
      for (std::size_t k = 0; k < n; ++k) {
        const DirectionSample& a = scalar[start + k];
        const DirectionSample& b = batch[k];
        ASSERT_TRUE(same_bits(a.direction.x, b.direction.x) && same_bits(a.direction.y, b.direction.y) &&
                    same_bits(a.direction.z, b.direction.z) && same_bits(a.pdf, b.pdf) && a.x == b.x && a.y == b.y)
            << what << ": length " << n << " from " << start << ", element " << k << " u = (" << u[start + k].x << ", "
            << u[start + k].y << ")";
      }
    }
  }
}

/// sample_texels == sample_texel, bit for bit, for the three built-in distributions of `weights` (w x h); the pdf
/// of every drawn sample finite and positive.
void expect_texels_match_scalar(const std::vector<float>& weights, int w, int h, const std::vector<Vec2>& u,
                                const std::string& what) {
  const CdfDistribution2D cdf(weights.data(), w, h);
  const AliasDistribution2D alias(weights.data(), w, h);
  const HierarchicalDistribution2D pyramid(weights.data(), w, h);
  for (const Distribution2D* d : {static_cast<const Distribution2D*>(&cdf), static_cast<const Distribution2D*>(&alias),
                                  static_cast<const Distribution2D*>(&pyramid)}) {
    std::vector<TexelSample> batch(u.size());
    d->sample_texels(u, batch);
    for (std::size_t k = 0; k < u.size(); ++k) {
      const TexelSample a = d->sample_texel(u[k]);
      ASSERT_TRUE(same_bits(a.fx, batch[k].fx) && same_bits(a.fy, batch[k].fy) && same_bits(a.pdf, batch[k].pdf) &&
                  a.x == batch[k].x && a.y == batch[k].y)
          << d->method() << " " << what << " element " << k;
      ASSERT_TRUE(std::isfinite(batch[k].pdf) && batch[k].pdf > 0.0) << d->method() << " " << what << " " << k;
    }
  }
}

}  // namespace

TEST(EnvSamplingBatch, EqualsScalarForEveryMethodAndGrid) {
  for (const Grid& g : kGrids) {
    BakeOptions o;
    o.grid = g.kind;
    o.compensated = true;
    const EnvTables t = EnvTables::bake(sky_map(g), o, g.name);
    const std::vector<Vec2> u = test_u(3000);
    for (bool compensated : {false, true})
      for (SamplingMethod m : kMethods) {
        const SphericalDistribution* d = t.distribution(m, compensated);
        ASSERT_NE(d, nullptr);
        expect_batch_matches_scalar(*d, u, g.name + " " + method_name(m) + (compensated ? " compensated" : ""));
      }
  }
}

TEST(EnvSamplingBatch, DistributionSampleTexelsEqualsSampleTexel) {
  // Odd and tall sizes directly on the 2D distributions (the marginal and the rows of every shape); 1031 x 517 and
  // 3 x 100003 have cdf rows too large for the caches, which cdf's grouped search is kept for.
  for (auto [w, h] : {std::pair{1, 1}, std::pair{3, 2}, std::pair{1, 77}, std::pair{200, 3}, std::pair{129, 65},
                      std::pair{1031, 517}, std::pair{3, 100003}}) {
    std::vector<float> weights(std::size_t(w) * h);
    std::mt19937_64 rng(std::uint64_t(w * 1000 + h));
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    for (float& v : weights) v = U(rng) < 0.2f ? 0.0f : U(rng);
    weights[weights.size() / 2] = 1e6f;
    expect_texels_match_scalar(weights, w, h, test_u(500), std::to_string(w) + "x" + std::to_string(h));
  }
}

TEST(EnvSamplingBatch, SampleTexelsEqualsSampleTexelAtTheExtremes) {
  // Weights that stress the arithmetic of the warps: no light at all (the uniform fallback), totals beyond 2^120
  // (the pyramid's scaled storage), denormals beside 1e30, one lit texel, and a constant map.
  const int w = 300, h = 150;
  std::vector<std::pair<std::string, std::vector<float>>> maps;
  maps.emplace_back("zero", std::vector<float>(std::size_t(w) * h, 0.0f));
  maps.emplace_back("huge", std::vector<float>(std::size_t(w) * h, 3e38f));
  std::vector<float> tiny(std::size_t(w) * h);
  for (std::size_t i = 0; i < tiny.size(); ++i) tiny[i] = i % 3 == 0 ? 1e-44f : i % 3 == 1 ? 0.0f : 1e-38f;
  tiny[tiny.size() / 3] = 1e30f;
  maps.emplace_back("denormals_and_a_sun", tiny);
  std::vector<float> one(std::size_t(w) * h, 0.0f);
  one[std::size_t(77) * w + 201] = 2.5f;
  maps.emplace_back("one_texel", one);
  maps.emplace_back("constant", std::vector<float>(std::size_t(w) * h, 1.0f));
  const std::vector<Vec2> u = test_u(1000);
  for (const auto& [name, weights] : maps) expect_texels_match_scalar(weights, w, h, u, name);
}

namespace {

/// A distribution that is not one of the built-ins (the default sample_texels loop and sample_general path).
class Wrapped final : public Distribution2D {
 public:
  Wrapped(const float* w, int width, int height) : Distribution2D(width, height), inner_(w, width, height) {
    integral_ = inner_.integral();
  }
  const char* method() const override { return "wrapped"; }
  DistributionSample sample(Vec2 u) const override { return inner_.sample(u); }
  double pdf(Vec2 uv) const override { return inner_.pdf(uv); }
  double texel_probability(int x, int y) const override { return inner_.texel_probability(x, y); }
  std::size_t bytes() const override { return inner_.bytes(); }

 private:
  HierarchicalDistribution2D inner_;
};

}  // namespace

TEST(EnvSamplingBatch, OtherDistributionsLoopTheScalarPath) {
  for (const Grid& g : {kGrids[0], kGrids[3], kGrids[4]}) {
    std::vector<float> weights(std::size_t(g.width) * g.height);
    for (std::size_t i = 0; i < weights.size(); ++i) weights[i] = float(1 + i % 13);
    const SphericalDistribution d(g.kind, std::make_shared<const Wrapped>(weights.data(), g.width, g.height));
    expect_batch_matches_scalar(d, test_u(500), g.name + " wrapped");
  }
}

// builtin() is what SphericalDistribution trusts to inline a class's pick(): each built-in class names itself, as its
// method() does, and a class defined elsewhere is Other (sampled through the virtual calls).
TEST(EnvSamplingBatch, BuiltinNamesTheClass) {
  const int W = 64, H = 32;
  std::vector<float> weights(std::size_t(W) * H, 1.0f);
  const auto fine = std::make_shared<const HierarchicalDistribution2D>(weights.data(), W, H);
  const std::uint64_t texel = 5;
  const float one = 1.0f;
  const std::vector<float> cells(std::size_t(fine->level_width(1)) * fine->level_height(1), 1.0f);
  const CdfDistribution2D cdf(weights.data(), W, H);
  const AliasDistribution2D alias(weights.data(), W, H);
  const SparseDistribution2D sparse(W, H, std::span(&texel, 1), std::span(&one, 1));
  const RefinedDistribution2D refined(fine, 1, cells);
  const Wrapped other(weights.data(), W, H);
  const std::pair<const Distribution2D*, BuiltinDistribution> expected[] = {
      {&cdf, BuiltinDistribution::Cdf},
      {&alias, BuiltinDistribution::Alias},
      {fine.get(), BuiltinDistribution::Hierarchical},
      {&sparse, BuiltinDistribution::Sparse},
      {&refined, BuiltinDistribution::Refined},
      {&other, BuiltinDistribution::Other}};
  const char* names[] = {"cdf", "alias", "hierarchical", "sparse", "refined", "wrapped"};
  for (std::size_t k = 0; k < std::size(expected); ++k) {
    EXPECT_EQ(expected[k].first->builtin(), expected[k].second) << names[k];
    EXPECT_STREQ(expected[k].first->method(), names[k]);
  }
}

TEST(EnvSamplingBatch, MismatchedLengthsAreAnError) {
  std::vector<float> weights(64 * 32, 1.0f);
  const SphericalDistribution d(Kind::LatLong, std::make_shared<const CdfDistribution2D>(weights.data(), 64, 32));
  std::vector<Vec2> u(10, Vec2(0.5, 0.5));
  std::vector<DirectionSample> out(9);
  EXPECT_THROW(d.sample(u, out), Error);
}
