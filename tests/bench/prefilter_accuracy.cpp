// The accuracy table of docs/PREFILTER.md ("Method and the accuracy knob"): for each chain size and accuracy, the
// relative RMS of every level (worst channel) against the brute-force GGX sum, and the CPU time of the chain, on a
// smooth sky, a textured sky and a textured sky with a 1e4 sun. A measurement, not a check (the checks are
// Prefilter.* in tests/ibl/test_prefilter.cpp).
// Usage: prefilter_accuracy [--sizes 8,16,...] [--accuracies 0.4,0.2,...] [MAP]
// (MAP, any map file, is area-resampled to 256 x 128 and measured too; default sizes 8..256, accuracies 0.4..0.05)
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/ibl/prefilter.h>
#include <envkit/maps/latlong.h>
#include <envkit/resample/resample.h>

#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <sstream>
#include <string>
#include <vector>

#include "prefilter_support.h"

using namespace envkit;
using namespace envkit::testing;

namespace {

struct Named {
  const char* name;
  const EnvMap* map;
};

void measure(const Named& k, int size, double accuracy) {
  PrefilterOptions o;
  o.size = size;
  o.accuracy = accuracy;
  const std::clock_t t0 = std::clock();  // CPU time of all threads: the machine may be shared
  const PrefilteredChain chain = prefilter_ggx(k.map->ref(), o);
  const double ms = 1000.0 * double(std::clock() - t0) / CLOCKS_PER_SEC;
  const LevelErrors e = compare_with_reference(*k.map, chain, 400);
  std::printf("%4d^2 accuracy %.2f %-8s source %4d %8.1f ms CPU:", size, accuracy, k.name, chain.source_size, ms);
  for (const auto& rms : e.rms) std::printf(" %.3f%%", 100.0 * worst_channel(rms));
  std::printf("\n");
}

// "8,16,32" -> {8, 16, 32}; empty on anything that is not a list of positive numbers.
std::vector<double> parse_list(const std::string& text) {
  std::vector<double> out;
  std::istringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || *end != '\0' || !(v > 0.0)) return {};
    out.push_back(v);
  }
  return out;
}

int usage() {
  std::fprintf(stderr, "usage: prefilter_accuracy [--sizes 8,16,...] [--accuracies 0.4,0.2,...] [MAP]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<double> sizes = {8, 16, 32, 64, 128, 256}, accuracies = {0.4, 0.2, 0.1, 0.05};
  std::string map_path;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if ((arg == "--sizes" || arg == "--accuracies") && i + 1 < argc) {
      (arg == "--sizes" ? sizes : accuracies) = parse_list(argv[++i]);
      if ((arg == "--sizes" ? sizes : accuracies).empty()) return usage();
    } else if (arg.rfind("-", 0) == 0 || !map_path.empty()) {
      return usage();
    } else {
      map_path = arg;
    }
  }
  try {
    const EnvMap smooth = latlong_env(256, smooth_sky), textured = textured_sky(256, 0.0f),
                 sunny = textured_sky(256, 1e4f);
    std::vector<Named> maps = {{"smooth", &smooth}, {"textured", &textured}, {"sun", &sunny}};
    EnvMap hdri;
    if (!map_path.empty()) {
      const EnvMap file = load_envmap(map_path);
      hdri.param = std::make_unique<LatLongMap>(256, 128);
      hdri.image = resample(file.ref(), *hdri.param, identity3());
      maps.push_back({"hdri", &hdri});
    }
    for (double size : sizes)
      for (double accuracy : accuracies)
        for (const Named& k : maps) measure(k, int(size), accuracy);
  } catch (const Error& e) {
    std::fprintf(stderr, "prefilter_accuracy: %s\n", e.what());
    return 1;
  }
  return 0;
}
