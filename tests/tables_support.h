#pragma once
/// @file tables_support.h
/// Test support: sampling tables baked from an analytic probe (header-only).
#include <envkit/envmap/envmap.h>
#include <envkit/probes.h>
#include <envkit/tables/env_tables.h>

#include <memory>

namespace envkit::test {

/// Every table (cdf, alias, hierarchical and their compensated twins) of `probe` rasterised into `param`, on the
/// bake grid `grid` (Kind::LatLong, Octahedral or HEALPix); `sun`: with the sun split of each (BakeOptions::sun).
inline EnvTables bake(const probes::Probe& probe, std::unique_ptr<Parameterization> param, Kind grid,
                      bool sun = false) {
  EnvMap map;
  map.image = probes::rasterize(probe, *param);
  map.param = std::move(param);
  BakeOptions options;
  options.grid = grid;
  options.compensated = true;
  options.sun = sun;
  return EnvTables::bake(map, options);
}

}  // namespace envkit::test
