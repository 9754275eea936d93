#include <envkit/core/error.h>
#include <envkit/envmap/map_compare.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/resample.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace envkit {

namespace {

// Colour channels of a map; a single channel is broadcast against the other
// map's channels.
std::vector<int> colour_channels(const Image& img) {
  std::vector<int> cs;
  for (int c = 0; c < img.channels; ++c)
    if (c != img.alpha_channel) cs.push_back(c);
  return cs;
}

double relative_difference(double a, double b) {
  if (a == b) return 0.0;
  return a == 0.0 ? std::numeric_limits<double>::infinity() : std::abs(b - a) / std::abs(a);
}

}  // namespace

MapComparison compare_maps(const EnvMap& A, const EnvMap& B, Filter filter, const std::string& path_a,
                           const std::string& path_b) {
  ResampleOptions ro;
  ro.filter = filter;
  const Image R = resample(B.ref(), *A.param, A.to_world(), ro);
  const std::vector<int> ca = colour_channels(A.image), cb = colour_channels(R);
  if (ca.size() != cb.size() && ca.size() != 1 && cb.size() != 1)
    fail(path_b, std::to_string(cb.size()) + " colour channels cannot be compared with the " +
                     std::to_string(ca.size()) + " of " + path_a);
  const std::size_t n = std::max(ca.size(), cb.size());
  // Where B has no data (a coverage channel the resampling added), the texel is
  // not compared.
  const int coverage = B.image.alpha_channel < 0 ? R.alpha_channel : -1;

  MapComparison cmp;
  for (std::size_t k = 0; k < n; ++k)
    cmp.channels.push_back(ca.size() == n ? A.image.channel_names[ca[k]] : R.channel_names[cb[k]]);
  const SolidAngleTable omega(*A.param);
  double se = 0, rel = 0, weight = 0;
  for (int j = 0; j < A.image.height; ++j) {
    for (int i = 0; i < A.image.width; ++i) {
      double w = omega(i, j);
      if (coverage >= 0) w *= R.at(i, j, coverage);
      if (w <= 0.0) continue;
      weight += w;
      for (std::size_t k = 0; k < n; ++k) {
        const double ref = A.image.at(i, j, ca[std::min(k, ca.size() - 1)]);
        const double img = R.at(i, j, cb[std::min(k, cb.size() - 1)]);
        const double d = img - ref;
        se += w * d * d;
        rel += w * d * d / (ref * ref + 1e-2);
        if (std::abs(d) > cmp.max.value) cmp.max = {std::abs(d), i, j, int(k), {}};
      }
    }
  }
  if (weight > 0.0) {
    cmp.rmse = std::sqrt(se / (weight * double(n)));
    cmp.relmse = rel / (weight * double(n));
  }
  cmp.compared_solid_angle = weight;
  if (cmp.max.i >= 0) {
    Vec3 d;
    A.param->to_direction(Vec2(cmp.max.i + 0.5, cmp.max.j + 0.5), d);
    cmp.max.direction = apply(A.to_world(), d);
  }

  // Power of each map on its own texels: resampling does not enter the flux
  // comparison.
  const std::vector<double> pa = total_power(A.image, *A.param);
  const std::vector<double> pb = total_power(B.image, *B.param);
  const std::vector<int> cb_own = colour_channels(B.image);
  for (std::size_t k = 0; k < n; ++k) {
    cmp.power_a.push_back(pa[ca[std::min(k, ca.size() - 1)]]);
    cmp.power_b.push_back(pb[cb_own[std::min(k, cb_own.size() - 1)]]);
    cmp.power_rel.push_back(relative_difference(cmp.power_a.back(), cmp.power_b.back()));
    cmp.power_max_rel = std::max(cmp.power_max_rel, cmp.power_rel.back());
  }
  return cmp;
}

double comparison_metric(const MapComparison& c, const std::string& metric) {
  if (metric == "rmse") return c.rmse;
  if (metric == "max") return c.max.value;
  if (metric == "power") return c.power_max_rel;
  return c.relmse;
}

}  // namespace envkit
