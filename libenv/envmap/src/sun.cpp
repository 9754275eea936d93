#include <envkit/core/vec.h>
#include <envkit/envmap/sun.h>
#include <envkit/io/color.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/resample/filter.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace envkit {

namespace {

/// The colour channels detect_sun reads: the first three that are not alpha (one channel stands for all three).
std::array<int, 3> colour_channels(const Image& image) {
  std::array<int, 3> c{};
  int n = 0;
  for (int k = 0; k < image.channels && n < 3; ++k)
    if (k != image.alpha_channel) c[std::size_t(n++)] = k;
  for (int k = std::max(n, 1); k < 3; ++k) c[std::size_t(k)] = c[0];
  return c;
}

double non_negative(float v) { return v > 0.0f && std::isfinite(v) ? double(v) : 0.0; }  // NaN, Inf, < 0: 0

}  // namespace

std::optional<SunEstimate> detect_sun(const EnvMap& map, const SunOptions& options) {
  const Image& image = map.image;
  const Parameterization& param = *map.param;
  if (image.texel_count() == 0 || image.channels == 0) return std::nullopt;
  const Vec3 weights = luminance_weights(options.colorspace);
  const std::array<int, 3> ch = colour_channels(image);
  const TexelSource source(image, param);
  const TexelDirections dirs(param);
  const SolidAngleTable omega(param);
  const Mat3 to_world = map.to_world();
  const int w = image.width;
  const auto rgb = [&](std::size_t t) {
    const float* px = image.pixels.data() + t * std::size_t(image.channels);
    return std::array<double, 3>{non_negative(px[ch[0]]), non_negative(px[ch[1]]), non_negative(px[ch[2]])};
  };
  const auto luminance = [&](const std::array<double, 3>& c) {
    return weights.x * c[0] + weights.y * c[1] + weights.z * c[2];
  };

  // The map's luminance power, median and brightest texel: rows in parallel, then combined in row order (the
  // same sums and the same first brightest texel whatever the thread count).
  const int h = image.height;
  const bool blanks = param.has_blank_texels();  // else every texel centre has a direction: no need to compute it
  const float uncovered = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> lum(image.texel_count());
  std::vector<double> row_power(std::size_t(h), 0.0), row_peak(std::size_t(h), -1.0);
  std::vector<std::size_t> row_peak_texel(std::size_t(h), 0);
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t t = std::size_t(y) * std::size_t(w) + std::size_t(x);
      Vec3 d;
      if (!source.covered(t) || (blanks && !dirs.centre(x, y, d))) {
        lum[t] = uncovered;
        continue;
      }
      const double l = luminance(rgb(t));
      lum[t] = float(l);
      row_power[std::size_t(y)] += l * omega(x, y);
      if (l > row_peak[std::size_t(y)]) row_peak[std::size_t(y)] = l, row_peak_texel[std::size_t(y)] = t;
    }
  });
  double total_power = 0.0, peak = -1.0;
  std::size_t peak_texel = 0;
  for (int y = 0; y < h; ++y) {
    total_power += row_power[std::size_t(y)];
    if (row_peak[std::size_t(y)] > peak) peak = row_peak[std::size_t(y)], peak_texel = row_peak_texel[std::size_t(y)];
  }
  if (blanks) lum.erase(std::remove_if(lum.begin(), lum.end(), [](float v) { return std::isnan(v); }), lum.end());
  if (lum.empty() || !(peak > 0.0) || !(total_power > 0.0)) return std::nullopt;
  const auto middle = lum.begin() + std::ptrdiff_t(lum.size() / 2);
  std::nth_element(lum.begin(), middle, lum.end());
  const double median = *middle;
  if (peak < options.min_contrast * median) return std::nullopt;

  // The region: bright texels near the peak.
  Vec3 peak_dir;
  dirs.centre(int(peak_texel % std::size_t(w)), int(peak_texel / std::size_t(w)), peak_dir);
  peak_dir = apply(to_world, peak_dir).normalized();
  const double threshold = std::sqrt(peak * std::max(median, peak * 1e-12));
  const double cos_search = std::cos(options.search_radius);
  SunEstimate sun;
  Vec3 centroid(0.0);
  double region_luminance_power = 0.0, max_value = 0.0;
  std::vector<std::size_t> region;
  for (std::size_t t = 0; t < image.texel_count(); ++t) {
    const std::array<double, 3> c = rgb(t);
    const double l = luminance(c);
    if (l < threshold) continue;  // most texels: no direction needed
    const int x = int(t % std::size_t(w)), y = int(t / std::size_t(w));
    Vec3 d;
    if (!source.covered(t) || !dirs.centre(x, y, d)) continue;
    d = apply(to_world, d).normalized();
    if ((d ^ peak_dir) < cos_search) continue;
    const double o = omega(x, y);
    region.push_back(t);
    sun.solid_angle += o;
    for (int k = 0; k < 3; ++k) sun.power[std::size_t(k)] += c[std::size_t(k)] * o;
    region_luminance_power += l * o;
    centroid += (l * o) * d;
    max_value = std::max({max_value, c[0], c[1], c[2]});
  }
  sun.texels = int(region.size());
  sun.angular_radius = safe_acos(1.0 - sun.solid_angle / kTwoPi);
  sun.power_share = region_luminance_power / total_power;
  if (sun.angular_radius > options.max_radius || sun.power_share < options.min_power_share) return std::nullopt;
  sun.direction = centroid.length() > 0.0 ? centroid.normalized() : peak_dir;
  for (int k = 0; k < 3; ++k) sun.radiance[std::size_t(k)] = sun.power[std::size_t(k)] / sun.solid_angle;
  sun.peak_luminance = peak;
  sun.median_luminance = median;
  // A clipped sun is a plateau: texels at exactly the region's largest channel value.
  for (std::size_t t : region) {
    const std::array<double, 3> c = rgb(t);
    if (std::max({c[0], c[1], c[2]}) == max_value) ++sun.clipped_texels;
  }
  sun.clipped =
      sun.clipped_texels >= 3 && 4 * sun.clipped_texels >= sun.texels && peak < options.clipped_contrast * median;
  sun.region = std::move(region);
  return sun;
}

}  // namespace envkit
