// The sun split (sun_split.h): the sun's texels and the residual partition the tables' light exactly, each part
// samples only its own texels, the bounding cone holds every sun sample, and maps without a sun are not split.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/octahedral.h>
#include <envkit/probes.h>
#include <envkit/tables/env_tables.h>
#include <envkit/tables/sun_split.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "tables_support.h"

using namespace envkit;

namespace {

using test::bake;

/// Every texel of the grid belongs to exactly one part: the sun's texels have residual density 0 and the sun's
/// density in proportion to their importance; every other lit texel has residual density in proportion to its
/// importance and sun density 0.
void expect_partition(const EnvTables& tables, const SunSplit& split) {
  const int W = tables.width(), H = tables.height();
  const std::span<const float> importance = tables.importance();
  const SphericalDistribution& sun = split.sun_distribution();
  const SphericalDistribution& residual = split.residual();
  double sun_power = 0.0, residual_power = 0.0;
  for (std::size_t t : split.sun().region) sun_power += importance[t] * sun.texel_solid_angle(int(t % W), int(t / W));
  residual_power = tables.total_importance() - sun_power;
  std::vector<char> in_sun(importance.size(), 0);
  for (std::size_t t : split.sun().region) in_sun[t] = 1;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const std::size_t t = std::size_t(y) * W + x;
      const double own = importance[t];
      if (in_sun[t]) {
        ASSERT_EQ(residual.texel_pdf(x, y), 0.0) << x << "," << y;
        EXPECT_NEAR(sun.texel_pdf(x, y), own / sun_power, 1e-5 * own / sun_power) << x << "," << y;
      } else {
        ASSERT_EQ(sun.texel_pdf(x, y), 0.0) << x << "," << y;
        EXPECT_NEAR(residual.texel_pdf(x, y), own / residual_power, 1e-4 * own / residual_power + 1e-12)
            << x << "," << y;
      }
    }
}

}  // namespace

TEST(SunSplit, TheTwoPartsPartitionTheLightOnLatLongAndOctahedralGrids) {
  const probes::SunProbe probe(Vec3(0.4, 0.5, -0.77).normalized(), 0.6 * kPi / 180.0, Vec3(2e4, 1.8e4, 1.5e4),
                               Vec3(0.3, 0.4, 0.6));
  struct Case {
    const char* name;
    EnvTables tables;
  };
  Case cases[] = {{"latlong 256x128", bake(probe, std::make_unique<LatLongMap>(256, 128), Kind::LatLong)},
                  {"octahedral 128", bake(probe, std::make_unique<OctahedralMap>(128), Kind::Octahedral)}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    for (SamplingMethod method : {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical}) {
      SCOPED_TRACE(method_name(method));
      const std::optional<SunSplit> split = SunSplit::make(c.tables, method, false);
      ASSERT_TRUE(split.has_value());
      EXPECT_GT(split->sun().power_share, 0.5);
      expect_partition(c.tables, *split);
    }
  }
}

TEST(SunSplit, SunSamplesLieInTheirTexelsAndInsideTheBoundingCone) {
  const probes::OutdoorProbe probe;  // the default probe: a 0.27 degree sun over a sky
  const EnvTables tables = bake(probe, std::make_unique<LatLongMap>(512, 256), Kind::LatLong);
  const std::optional<SunSplit> split = SunSplit::make(tables, SamplingMethod::Hierarchical, false);
  ASSERT_TRUE(split.has_value());
  const Vec3 axis = split->sun().direction;
  EXPECT_GT(split->cos_bound(), std::cos(3.0 * kPi / 180.0));  // a small cone: the test before a search pays
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (int i = 0; i < 20000; ++i) {
    const DirectionSample s = split->sun_distribution().sample(Vec2(u01(rng), u01(rng)));
    ASSERT_GT(s.pdf, 0.0);
    ASSERT_GE(s.direction ^ axis, split->cos_bound()) << "a sun sample outside the cone";
    ASSERT_EQ(split->sun_distribution().pdf(s.direction), s.pdf);
    ASSERT_EQ(split->residual().pdf(s.direction), 0.0);
    const DirectionSample r = split->residual().sample(Vec2(u01(rng), u01(rng)));
    ASSERT_EQ(split->sun_distribution().pdf(r.direction), 0.0);
  }
}

TEST(SunSplit, CompensatedResidualKeepsTheSunOut) {
  const probes::OutdoorProbe probe;
  const EnvTables tables = bake(probe, std::make_unique<LatLongMap>(256, 128), Kind::LatLong);
  const std::optional<SunSplit> split = SunSplit::make(tables, SamplingMethod::Hierarchical, true);
  ASSERT_TRUE(split.has_value());
  const int W = tables.width();
  for (std::size_t t : split->sun().region) EXPECT_EQ(split->residual().texel_pdf(int(t % W), int(t / W)), 0.0);
  // Compensation removes the residual's mean: its dimmest lit texels get density 0, the brightest keep some.
  int zero = 0;
  for (int y = 0; y < tables.height(); ++y)
    for (int x = 0; x < W; ++x) zero += split->residual().texel_pdf(x, y) == 0.0;
  EXPECT_GT(zero, int(split->sun().region.size()));
}

// A map whose only light is its sun: the rest would be an empty table, whose uniform fallback would draw the sun's
// texels too and count the sun twice. Not split: one table samples the sun as well.
TEST(SunSplit, ASunThatIsAllTheLightIsNotSplit) {
  const probes::SunProbe probe(Vec3(0.4, 0.5, -0.77).normalized(), 1.0 * kPi / 180.0, Vec3(1e3), Vec3(0.0));
  const EnvTables tables = bake(probe, std::make_unique<LatLongMap>(256, 128), Kind::LatLong, /*sun=*/true);
  for (bool compensated : {false, true})
    EXPECT_FALSE(SunSplit::make(tables, SamplingMethod::Hierarchical, compensated).has_value());
  const auto stored = tables.stored_sun_split(SamplingMethod::Hierarchical, false);
  ASSERT_TRUE(stored.has_value());
  EXPECT_EQ(*stored, nullptr);
}

TEST(SunSplit, MapsWithoutASunAreNotSplit) {
  const probes::GradientProbe sky(Vec3(0.2), Vec3(1.0), probes::GradientProbe::Form::Quadratic);
  const EnvTables tables = bake(sky, std::make_unique<LatLongMap>(256, 128), Kind::LatLong);
  EXPECT_FALSE(SunSplit::make(tables, SamplingMethod::Hierarchical, false).has_value());
}

namespace {

/// Both splits give every texel the same density, bit for bit, and draw the same samples.
void expect_same_split(const SunSplit& a, const SunSplit& b) {
  ASSERT_EQ(a.sun().region, b.sun().region);
  EXPECT_EQ(a.cos_bound(), b.cos_bound());
  EXPECT_EQ(a.sun().direction.x, b.sun().direction.x);
  EXPECT_EQ(a.sun().power_share, b.sun().power_share);
  EXPECT_EQ(a.sun().clipped, b.sun().clipped);
  const SphericalDistribution& grid = a.residual();
  for (int y = 0; y < grid.height(); ++y)
    for (int x = 0; x < grid.width(); ++x) {
      ASSERT_EQ(a.residual().texel_pdf(x, y), b.residual().texel_pdf(x, y)) << x << "," << y;
      ASSERT_EQ(a.sun_distribution().texel_pdf(x, y), b.sun_distribution().texel_pdf(x, y)) << x << "," << y;
    }
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (int i = 0; i < 2000; ++i) {
    const Vec2 u(u01(rng), u01(rng));
    ASSERT_EQ(a.residual().sample(u).direction.x, b.residual().sample(u).direction.x);
    ASSERT_EQ(a.sun_distribution().sample(u).pdf, b.sun_distribution().sample(u).pdf);
  }
}

std::string temp_table(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("envkit_sun_" + name + ".envtbl")).string();
}

std::string load_error(const std::string& path) {
  try {
    EnvTables::load(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(SunSplitStored, EveryTableKeepsTheSplitMakeBuildsThroughAFile) {
  const probes::OutdoorProbe probe;
  const EnvTables baked = bake(probe, std::make_unique<LatLongMap>(256, 128), Kind::LatLong, /*sun=*/true);
  const std::string path = temp_table("stored");
  baked.save(path);
  const EnvTables loaded = EnvTables::load(path);
  std::filesystem::remove(path);
  for (bool compensated : {false, true})
    for (SamplingMethod method : {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical}) {
      SCOPED_TRACE(std::string(method_name(method)) + (compensated ? " compensated" : ""));
      const std::optional<SunSplit> made = SunSplit::make(baked, method, compensated);
      ASSERT_TRUE(made.has_value());
      for (const EnvTables* tables : {&baked, &loaded}) {
        const auto stored = tables->stored_sun_split(method, compensated);
        ASSERT_TRUE(stored.has_value());
        ASSERT_NE(*stored, nullptr);
        expect_same_split(*made, **stored);
      }
    }
}

TEST(SunSplitStored, ABakeRecordsThatItFoundNoSunAndOneThatDidNotLook) {
  const probes::GradientProbe sky(Vec3(0.2), Vec3(1.0), probes::GradientProbe::Form::Quadratic);
  const EnvTables looked = bake(sky, std::make_unique<LatLongMap>(64, 32), Kind::LatLong, /*sun=*/true);
  const EnvTables not_looked = bake(sky, std::make_unique<LatLongMap>(64, 32), Kind::LatLong);
  const std::string path = temp_table("none");
  looked.save(path);
  const EnvTables loaded = EnvTables::load(path);
  std::filesystem::remove(path);
  for (const EnvTables* tables : {&looked, &loaded}) {
    const auto stored = tables->stored_sun_split(SamplingMethod::Hierarchical, false);
    ASSERT_TRUE(stored.has_value());
    EXPECT_EQ(*stored, nullptr);
  }
  EXPECT_FALSE(not_looked.stored_sun_split(SamplingMethod::Hierarchical, false).has_value());
}

// A checksum says only that the bytes are as written: the sun's values are checked too.
TEST(SunSplitStored, InvalidSunValuesBehindValidChecksumsAreRefused) {
  const probes::OutdoorProbe probe;
  BakeOptions options;
  options.cdf = options.alias = false;
  options.sun = true;
  EnvMap map;
  map.param = std::make_unique<LatLongMap>(128, 64);
  map.image = probes::rasterize(probe, *map.param);
  const std::string path = temp_table("corrupt");
  EnvTables::bake(map, options).save(path);
  std::vector<std::byte> good;
  {
    std::ifstream f(path, std::ios::binary);
    const std::vector<char> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    good.resize(bytes.size());
    std::memcpy(good.data(), bytes.data(), bytes.size());
  }
  std::size_t sun_offset = 0;
  for (const TableFileSection& s : table_file_sections(good))
    if (s.name == "sun") sun_offset = s.offset;
  ASSERT_GT(sun_offset, 0u);
  // Word 0 is the flag, words 1-3 the direction, 15 the bound (sun_split.cpp's save_sun order).
  const auto patched = [&](std::size_t word, double value) {
    std::vector<std::byte> bytes = good;
    std::memcpy(bytes.data() + sun_offset + 8 * word, &value, 8);
    reseal_table_file(bytes);
    std::ofstream(path, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    return load_error(path);
  };
  EXPECT_EQ(patched(1,
                    [&] {
                      double v;
                      std::memcpy(&v, good.data() + sun_offset + 8, 8);
                      return v;
                    }()),
            "");
  EXPECT_NE(patched(1, std::nan("")).find("section sun: invalid sun (direction"), std::string::npos);
  EXPECT_NE(patched(2, 5.0).find("invalid sun (direction"), std::string::npos);
  EXPECT_NE(patched(15, 2.0).find("invalid sun (bound"), std::string::npos);
  std::uint64_t two = 2;
  double as_double;
  std::memcpy(&as_double, &two, 8);
  EXPECT_NE(patched(0, as_double).find("section sun: invalid flag"), std::string::npos);
  std::filesystem::remove(path);
}

// A residual that still holds the sun would count the sun twice (the parts are weighed as disjoint): refused.
TEST(SunSplitStored, AResidualWithTheSunInItIsRefused) {
  const probes::OutdoorProbe probe;
  const EnvTables tables = bake(probe, std::make_unique<LatLongMap>(256, 128), Kind::LatLong);
  const std::optional<SunSplit> split = SunSplit::make(tables, SamplingMethod::Hierarchical, false);
  ASSERT_TRUE(split.has_value());
  BlobWriter out;
  split->save_sun(out);
  const std::vector<std::byte> blob = out.flatten();
  const auto restore = [&](const StoredTable& residual) {
    BlobReader in(blob.data(), blob.size(), "sun");
    const std::shared_ptr<const StoredTable> shared(&residual, [](const StoredTable*) {});
    return SunSplit::restore(in, tables.grid(), tables.width(), tables.height(), shared);
  };
  EXPECT_EQ(restore(split->residual()).sun().region, split->sun().region);
  try {
    restore(*tables.distribution(SamplingMethod::Hierarchical));  // the whole map: the sun is in it
    ADD_FAILURE() << "a residual holding the sun was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("light on the sun's texels"), std::string::npos) << e.what();
  }
}
