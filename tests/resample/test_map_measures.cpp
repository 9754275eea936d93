// compare_maps (map_compare.h), map_statistics (map_stats.h) and matching_natural_size (map_size.h): the numbers
// envdiff, envinfo and envconvert print, checked against closed forms on constant and two-valued maps.
#include <envkit/core/error.h>
#include <envkit/envmap/map_compare.h>
#include <envkit/envmap/map_stats.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/param_factory.h>
#include <envkit/resample/map_size.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

namespace {

using namespace envkit;

EnvMap constant_map(Kind kind, int n, float value, int channels = 3) {
  EnvMap m;
  m.param = make_parameterization(spec_for(kind, n, convention("envkit")));
  m.image = Image(m.param->width(), m.param->height(), channels);
  m.image.channel_names = default_channel_names(channels);
  for (float& v : m.image.pixels) v = value;
  return m;
}

TEST(MapStatistics, ConstantMapHasClosedFormPower) {
  for (Kind kind : {Kind::LatLong, Kind::CubeMap, Kind::Octahedral}) {
    const MapStats s = map_statistics(constant_map(kind, 16, 2.5f));
    EXPECT_NEAR(s.solid_angle, 4 * kPi, 1e-12);
    ASSERT_EQ(s.channels.size(), 3u);
    for (const ChannelStats& c : s.channels) {
      // Per-texel solid angles of non-lat-long maps are stored as floats (relative precision 6e-8).
      EXPECT_NEAR(c.power, 2.5 * 4 * kPi, 2.5 * 4 * kPi * 1e-7);
      EXPECT_NEAR(c.mean_radiance, 2.5, 2.5e-7);
      EXPECT_EQ(c.min, 2.5);
      EXPECT_EQ(c.max, 2.5);
      EXPECT_EQ(c.texel_mean, 2.5);
    }
  }
}

TEST(CompareMaps, ConstantMapsAcrossParameterizations) {
  const EnvMap a = constant_map(Kind::LatLong, 16, 2.0f);
  const EnvMap b = constant_map(Kind::CubeMap, 12, 3.0f);
  const MapComparison c = compare_maps(a, b, Filter::Area);
  // B resampled onto A stays exactly 3 (area keeps constants constant): every texel differs by exactly 1.
  EXPECT_NEAR(c.rmse, 1.0, 1e-6);
  EXPECT_NEAR(c.relmse, 1.0 / (4.0 + 1e-2), 1e-6);
  EXPECT_NEAR(c.max.value, 1.0, 1e-6);
  EXPECT_NEAR(c.compared_solid_angle, 4 * kPi, 1e-9);
  ASSERT_EQ(c.power_rel.size(), 3u);
  for (double r : c.power_rel) EXPECT_NEAR(r, 0.5, 1e-7);
  EXPECT_NEAR(comparison_metric(c, "power"), 0.5, 1e-7);
  EXPECT_EQ(comparison_metric(c, "rmse"), c.rmse);
  EXPECT_EQ(comparison_metric(c, "max"), c.max.value);
  EXPECT_EQ(comparison_metric(c, "relmse"), c.relmse);
  // A map against itself.
  const MapComparison same = compare_maps(a, a, Filter::Area);
  EXPECT_EQ(same.rmse, 0.0);
  EXPECT_EQ(same.power_max_rel, 0.0);
  EXPECT_EQ(same.max.i, -1);
}

TEST(CompareMaps, MaxErrorNamesItsTexelAndDirection) {
  EnvMap a = constant_map(Kind::LatLong, 8, 1.0f);
  EnvMap b = constant_map(Kind::LatLong, 8, 1.0f);
  b.image.at(5, 3, 1) = 4.0f;  // one texel of G
  const MapComparison c = compare_maps(a, b, Filter::Nearest);
  EXPECT_EQ(c.max.value, 3.0);
  EXPECT_EQ(c.max.i, 5);
  EXPECT_EQ(c.max.j, 3);
  EXPECT_EQ(c.channels[c.max.channel], "G");
  Vec3 d;
  a.param->to_direction(Vec2(5.5, 3.5), d);
  EXPECT_NEAR((c.max.direction - d).length(), 0.0, 1e-12);
}

TEST(CompareMaps, IncompatibleChannelsNameBothFiles) {
  const EnvMap a = constant_map(Kind::LatLong, 8, 1.0f, 3);
  EnvMap b = constant_map(Kind::LatLong, 8, 1.0f, 2);
  b.image.alpha_channel = -1;  // two colour channels
  try {
    compare_maps(a, b, Filter::Area, "a.exr", "b.exr");
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "b.exr: 2 colour channels cannot be compared with the 3 of a.exr");
  }
  // One channel is compared with every channel of the other.
  const EnvMap y = constant_map(Kind::LatLong, 8, 2.0f, 1);
  EXPECT_NEAR(compare_maps(a, y, Filter::Area).rmse, 1.0, 1e-6);
}

TEST(MatchingNaturalSize, KeepsTheTexelCount) {
  const Convention& conv = convention("envkit");
  // 2048 x 1024 = 2 Mi texels: lat-long N = 1024; cube 6 N^2 -> N = 591.2 -> 592 (multiple of 8);
  // octahedral N^2 -> 1448.2 -> 1448.
  EXPECT_EQ(matching_natural_size(2048u * 1024u, Kind::LatLong, conv), 1024);
  EXPECT_EQ(matching_natural_size(2048u * 1024u, Kind::CubeMap, conv), 592);
  EXPECT_EQ(matching_natural_size(2048u * 1024u, Kind::Octahedral, conv), 1448);
  EXPECT_EQ(matching_natural_size(50, Kind::Octahedral, conv), 7);  // below 64: rounded, not to 8
  EXPECT_EQ(matching_natural_size(0, Kind::LatLong, conv), 1);
  // A mirror ball holds data on about pi/4 of its square: the chosen ball holds about as many data texels.
  const int ball = matching_natural_size(1000000, Kind::MirrorBall, conv);
  EXPECT_GT(ball, 1000);
  const EnvMap big = constant_map(Kind::MirrorBall, ball, 1.0f, 1);
  // The share is measured on a 64-texel ball, whose partly covered rim texels weigh more than on a big one.
  EXPECT_NEAR(double(data_texel_count(big.image, *big.param)), 1e6, 0.04e6);
  const EnvMap m = constant_map(Kind::MirrorBall, 64, 1.0f);
  const std::size_t covered = data_texel_count(m.image, *m.param);
  EXPECT_LT(covered, std::size_t(64 * 64));
  EXPECT_NEAR(double(covered) / (64 * 64), kPi / 4, 0.03);
}

}  // namespace
