// Warnings of a bake are typed (TableWarning::Cause), and the cause survives a table file's save/load round trip,
// which stores the messages only.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

using namespace envkit;
using Cause = TableWarning::Cause;

namespace {

/// A 16 x 8 lat-long of `value`, with rows [zero_from, 8) black.
EnvMap latlong(float value, int zero_from = 8) {
  EnvMap m;
  m.param = std::make_unique<LatLongMap>(16, 8);
  m.image = Image(16, 8, 3);
  for (int y = 0; y < std::min(zero_from, 8); ++y)
    for (int x = 0; x < 16 * 3; ++x) m.image.pixels[std::size_t(y) * 16 * 3 + x] = value;
  return m;
}

EnvTables bake(const EnvMap& m, bool compensated) {
  BakeOptions o;
  o.compensated = compensated;
  return EnvTables::bake(m, o);
}

std::vector<Cause> causes(const EnvTables& t) {
  std::vector<Cause> c;
  for (const TableWarning& w : t.warnings()) c.push_back(w.cause);
  return c;
}

/// The tables after a save and a load.
EnvTables round_trip(const EnvTables& t, const std::string& name) {
  const std::string path = (std::filesystem::temp_directory_path() / (name + ".envtbl")).string();
  t.save(path);
  EnvTables loaded = EnvTables::load(path);
  std::filesystem::remove(path);
  return loaded;
}

void expect_same_warnings(const EnvTables& a, const EnvTables& b) {
  ASSERT_EQ(a.warnings().size(), b.warnings().size());
  for (std::size_t i = 0; i < a.warnings().size(); ++i) {
    EXPECT_EQ(a.warnings()[i].cause, b.warnings()[i].cause) << i;
    EXPECT_EQ(a.warnings()[i].message, b.warnings()[i].message) << i;
  }
}

}  // namespace

TEST(TableWarnings, AConstantMapsCompensatedTablesAreThePlainOnes) {
  const EnvTables t = bake(latlong(2.0f), true);
  ASSERT_EQ(causes(t), std::vector<Cause>{Cause::CompensatedFallback});
  EXPECT_TRUE(t.warnings()[0].concerns_compensated_tables());
  EXPECT_NE(t.warnings()[0].message.find("compensated tables are the plain ones"), std::string::npos);
  expect_same_warnings(t, round_trip(t, "warn_constant"));
  // Without compensated tables there is nothing to warn about.
  EXPECT_TRUE(bake(latlong(2.0f), false).warnings().empty());
}

TEST(TableWarnings, ABlackMapCarriesNoLight) {
  const EnvTables t = bake(latlong(0.0f), true);
  ASSERT_EQ(causes(t), (std::vector<Cause>{Cause::NoLight, Cause::CompensatedFallback}));
  EXPECT_FALSE(t.warnings()[0].concerns_compensated_tables());
  expect_same_warnings(t, round_trip(t, "warn_black"));
}

TEST(TableWarnings, ZeroRowsConcernEveryTable) {
  const EnvTables t = bake(latlong(1.0f, 5), true);
  ASSERT_EQ(causes(t), std::vector<Cause>{Cause::ZeroRows});
  EXPECT_FALSE(t.warnings()[0].concerns_compensated_tables());
  EXPECT_EQ(t.warnings()[0].message.rfind("3 all-zero rows", 0), 0u) << t.warnings()[0].message;
  expect_same_warnings(t, round_trip(t, "warn_rows"));
}

TEST(TableWarnings, NoWarningsForAnOrdinaryMap) {
  EnvMap m = latlong(1.0f);
  m.image.pixels[5] = 50.0f;
  const EnvTables t = bake(m, true);
  EXPECT_TRUE(t.warnings().empty());
  EXPECT_TRUE(round_trip(t, "warn_none").warnings().empty());
}
