#pragma once
// Shared by the prefilter tests: analytic test environments rasterised into
// maps, and error measures.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/texel_directions.h>

#include <cmath>
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

}  // namespace envkit::testing
