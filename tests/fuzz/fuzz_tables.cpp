// libFuzzer target: the table-file loader (EnvTables::load, libenv/tables/src/env_tables_file.cpp).
//
// Input: the bytes of a table file. They are written to a scratch file and loaded; a load must either throw
// envkit::Error naming the file, or give tables whose distributions can be sampled (a few samples and pdf lookups
// per baked method). Anything else is a finding.
// Seed: with ENVKIT_FUZZ_WRITE_SEED=<path> the target bakes a small valid table file (16x8 lat-long, every
// method, compensated twins) to <path> and exits; scripts/fuzz.sh does this before fuzzing, so the seed always
// has the current format version.
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/tables/env_tables.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

#include "fuzz_support.h"
#include "seed_tables.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  envkit::fuzz::run_on_one_thread();
  if (const char* seed = std::getenv("ENVKIT_FUZZ_WRITE_SEED")) {
    envkit::fuzz::write_seed_tables(seed);
    std::exit(0);
  }
  envkit::fuzz::scratch_dir("tables");
  envkit::fuzz::leave_signals_to_libfuzzer();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  envkit::fuzz::load_and_check(envkit::fuzz::write_input(data, size), [](const envkit::EnvTables& tables) {
    for (auto method :
         {envkit::SamplingMethod::Cdf, envkit::SamplingMethod::Alias, envkit::SamplingMethod::Hierarchical})
      for (bool comp : {false, true}) {
        const envkit::SphericalDistribution* d = tables.distribution(method, comp);
        if (!d) continue;
        for (double u : {0.0, 0.3, 0.7, 0.999999}) {
          const envkit::DirectionSample s = d->sample(envkit::Vec2(u, 1.0 - u));
          if (!std::isfinite(s.pdf) || s.pdf < 0) envkit::fuzz::finding("a sample with a non-finite or negative pdf");
          (void)d->pdf(s.direction);
        }
      }
  });
  return 0;
}
