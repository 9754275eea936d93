#pragma once
// Shared by the prefilter tests: analytic test environments rasterised into
// maps, and error measures.
#include <envkit/envmap/envmap.h>
#include <envkit/ibl/prefilter.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/texel_directions.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <vector>

namespace envkit::testing {

using RadianceFn = std::function<Vec3(const Vec3&)>;

// Smooth, strictly positive, with a broad bright blob so that every roughness
// level changes it.
inline Vec3 smooth_sky(const Vec3& d) {
  const Vec3 blob = Vec3(0.3, 0.5, 0.8).normalized();
  const double b = std::exp(6.0 * ((d ^ blob) - 1.0));
  return Vec3(0.4 + 0.3 * d.y + 2.0 * b, 0.5 + 0.2 * d.x * d.z + 1.5 * b, 0.7 + 0.25 * d.y * d.y + 1.0 * b);
}

// Rasterises f at texel centres of a map.
inline Image rasterize(const Parameterization& p, const RadianceFn& f) {
  Image img(p.width(), p.height(), 3);
  img.channel_names = {"R", "G", "B"};
  const TexelDirections dirs(p);
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      Vec3 d;
      if (!dirs.centre(i, j, d)) continue;
      const Vec3 v = f(d);
      img.at(i, j, 0) = float(v.x);
      img.at(i, j, 1) = float(v.y);
      img.at(i, j, 2) = float(v.z);
    }
  return img;
}

// A lat-long EnvMap (envkit convention) of f.
inline EnvMap latlong_env(int width, const RadianceFn& f) {
  EnvMap map;
  map.param = std::make_unique<LatLongMap>(width, width / 2);
  map.image = rasterize(*map.param, f);
  return map;
}

// Relative RMS error per channel: sqrt(sum (a - b)^2 / sum b^2).
struct RelRms {
  std::vector<double> err2, ref2;
  explicit RelRms(int channels) : err2(channels, 0.0), ref2(channels, 0.0) {}
  void add(int c, double value, double reference) {
    err2[c] += (value - reference) * (value - reference);
    ref2[c] += reference * reference;
  }
  double operator()(int c) const { return ref2[c] > 0.0 ? std::sqrt(err2[c] / ref2[c]) : 0.0; }
};

// Prefiltered levels against the brute-force GGX sum (GgxReference).
struct LevelErrors {
  std::vector<std::array<double, 3>> rms;  // per level >= 1, per channel
  std::vector<double> max_rel;             // per level: largest |P - R| / R over texels and channels
};

// Every level >= 1 against the brute-force sum, at every texel of a level or, past max_texels, at every stride-th
// texel (a regular subset, so the relative RMS is that of the whole level up to sampling).
inline LevelErrors compare_with_reference(const EnvMap& src, const PrefilteredChain& chain,
                                          std::size_t max_texels = SIZE_MAX) {
  const GgxReference reference(src.ref());
  LevelErrors e;
  for (std::size_t m = 1; m < chain.levels.size(); ++m) {
    const EnvMap& level = chain.levels[m];
    const TexelDirections dirs(*level.param);
    const std::size_t count = level.image.texel_count();
    const std::size_t stride = count > max_texels ? (count + max_texels - 1) / max_texels : 1;
    RelRms rms(3);
    double max_rel = 0.0;
    for (std::size_t t = stride / 2; t < count; t += stride) {
      const int x = int(t % level.image.width), y = int(t / level.image.width);
      Vec3 d;
      if (!dirs.centre(x, y, d)) continue;
      double ref[3];
      reference.eval(apply(level.to_world(), d).normalized(), chain.alpha[m], ref);
      for (int c = 0; c < 3; ++c) {
        rms.add(c, level.image.at(x, y, c), ref[c]);
        max_rel = std::max(max_rel, std::abs(level.image.at(x, y, c) - ref[c]) / ref[c]);
      }
    }
    e.rms.push_back({rms(0), rms(1), rms(2)});
    e.max_rel.push_back(max_rel);
  }
  return e;
}

inline double worst_channel(const std::array<double, 3>& rms) { return std::max({rms[0], rms[1], rms[2]}); }

// What a real HDRI holds that a smooth sky does not: texture at the source's own resolution (a checker of 2 x 2
// texels, +-50%, over smooth_sky) and, if sun > 0, a sun of that radiance in one texel.
inline EnvMap textured_sky(int width, float sun) {
  EnvMap map = latlong_env(width, smooth_sky);
  for (int y = 0; y < map.image.height; ++y)
    for (int x = 0; x < map.image.width; ++x)
      for (int c = 0; c < 3; ++c) map.image.at(x, y, c) *= ((x / 2 + y / 2) % 2 == 0) ? 1.5f : 0.5f;
  if (sun > 0.0f)
    for (int c = 0; c < 3; ++c) map.image.at(width * 3 / 10, map.image.height * 5 / 16, c) = sun;
  return map;
}

}  // namespace envkit::testing
