#pragma once
/// @file seed_tables.h
/// What the table fuzzers (fuzz_tables, fuzz_table_values) share: the valid table files they start from (a 16 x 8
/// lat-long with one bright texel, every method and the compensated twins; one with a stored sun split), writing an
/// input to the scratch directory, and the contract of a load (an envkit::Error naming the file, or tables that pass
/// the caller's checks; anything else is a finding).
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/tables/env_tables.h>

#include <cstdio>
#include <exception>
#include <fstream>
#include <memory>
#include <string>

#include "fuzz_support.h"

namespace envkit::fuzz {

/// Reports a finding on stderr and stops the process (libFuzzer saves the input).
[[noreturn]] inline void finding(const std::string& what) {
  std::fprintf(stderr, "FINDING: %s\n", what.c_str());
  std::fflush(stderr);
  __builtin_trap();
}

/// Writes `size` bytes to input.envtables in the scratch directory; returns its path.
inline std::string write_input(const void* data, std::size_t size) {
  const std::string path = (scratch_dir() / "input.envtables").string();
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

/// Loads `path` and runs `check` on the tables; a load that fails must throw envkit::Error naming the file.
template <class Check>
void load_and_check(const std::string& path, const Check& check) {
  try {
    check(EnvTables::load(path));
  } catch (const Error& e) {
    if (std::string(e.what()).find(path) == std::string::npos)
      finding(std::string("load error does not name the file: ") + e.what());
  } catch (const std::exception& e) {
    finding(std::string("EnvTables::load threw a non-envkit exception: ") + e.what());
  }
}

/// A `width` x `height` lat-long map: `bright` at texel (bright_x, bright_y), sky(x, y, c) elsewhere.
template <class Sky>
EnvMap seed_map(int width, int height, int bright_x, int bright_y, float bright, const Sky& sky) {
  EnvMap map;
  map.image = Image(width, height, 3);
  map.image.channel_names = default_channel_names(3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int c = 0; c < 3; ++c) map.image.at(x, y, c) = (x == bright_x && y == bright_y) ? bright : sky(x, y, c);
  map.param = std::make_unique<LatLongMap>(width, height);
  return map;
}

inline void write_seed_tables(const std::string& path) {
  const EnvMap map = seed_map(16, 8, 5, 2, 50.0f, [](int, int y, int c) { return 0.1f + 0.05f * float(y + c); });
  BakeOptions options;
  options.compensated = true;
  EnvTables::bake(map, options, "seed.exr").save(path);
}

/// A table file with a stored sun split (BakeOptions::sun): a 128 x 64 lat-long (the smallest whose texels are small
/// enough for a sun) with one sun texel over a sky, the hierarchical table only, to keep each fuzz run cheap.
inline void write_sun_seed_tables(const std::string& path) {
  const EnvMap map = seed_map(128, 64, 40, 20, 5e4f,
                              [](int x, int y, int c) { return 0.1f + 0.005f * float(y + c) + 0.001f * float(x % 7); });
  BakeOptions options;
  options.cdf = options.alias = false;
  options.sun = true;
  EnvTables::bake(map, options, "sun.exr").save(path);
}

}  // namespace envkit::fuzz
