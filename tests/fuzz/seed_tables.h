#pragma once
/// @file seed_tables.h
/// The valid table file the table fuzzers start from: a 16 x 8 lat-long with one bright texel, every method and
/// the compensated twins.
#include <envkit/env_tables.h>
#include <envkit/envmap.h>
#include <envkit/latlong.h>

#include <memory>
#include <string>

namespace envkit::fuzz {

inline void write_seed_tables(const std::string& path) {
  EnvMap map;
  map.image = Image(16, 8, 3);
  map.image.channel_names = default_channel_names(3);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x)
      for (int c = 0; c < 3; ++c) map.image.at(x, y, c) = (x == 5 && y == 2) ? 50.0f : 0.1f + 0.05f * float(y + c);
  map.param = std::make_unique<LatLongMap>(16, 8);
  BakeOptions options;
  options.compensated = true;
  EnvTables::bake(map, options, "seed.exr").save(path);
}

}  // namespace envkit::fuzz
