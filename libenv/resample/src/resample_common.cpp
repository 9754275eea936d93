#include "resample_common.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <utility>

namespace envkit::detail {

void ProgressCounter::add(std::size_t n) {
  if (!fn_) return;
  const std::size_t before = done_.fetch_add(n);
  const std::size_t step = std::max<std::size_t>(total_ / 100, 1);
  if ((before + n) / step != before / step) {
    std::lock_guard<std::mutex> lock(mutex_);
    fn_(std::min(1.0, double(before + n) / double(total_)));
  }
}

OutputLayout output_layout(const Image& src, const TexelSource& source) {
  OutputLayout o;
  o.channels = src.channels;
  o.alpha = src.alpha_channel;
  if (src.alpha_channel < 0 && !source.fully_covered()) {
    o.add_coverage = true;
    o.alpha = src.channels;
    o.channels = src.channels + 1;
  }
  return o;
}

Image make_output(const Image& src, const Parameterization& dst, const OutputLayout& o) {
  Image out(dst.width(), dst.height(), o.channels);
  out.channel_names = src.channel_names;
  if (o.add_coverage) out.channel_names.push_back("A");
  out.alpha_channel = o.alpha;
  out.metadata = src.metadata;
  return out;
}

std::ptrdiff_t coincident_source_texel(const Parameterization& src, const Parameterization& dst, const Mat3& dst_to_src,
                                       bool rotate, int i, int j, Vec2 centre_pos) {
  // Positions agree to far better than this after a direction round trip (about 1e-12 texels at 16k).
  constexpr double kTolerance = 1e-6;
  const auto offset_is = [](double x, double target) { return std::abs(x - std::floor(x) - target) <= kTolerance; };
  if (!offset_is(centre_pos.x, 0.5) || !offset_is(centre_pos.y, 0.5)) return -1;
  const int si = static_cast<int>(std::floor(centre_pos.x)), sj = static_cast<int>(std::floor(centre_pos.y));
  if (si < 0 || sj < 0 || si >= src.width() || sj >= src.height()) return -1;
  // Solid angles only for the rare candidates (no table: a disk map's table costs an integral per texel).
  const double omega_s = src.texel_solid_angle(si, sj);
  if (!(omega_s > 0.0) || std::abs(dst.texel_solid_angle(i, j) - omega_s) > kTolerance * omega_s) return -1;
  // The four quarter points of the output texel must land on the four quarter points of that source texel: the
  // texel maps onto it whole (a shift, quarter turn or flip), not merely through its centre.
  unsigned seen = 0;
  for (const double b : {0.25, 0.75})
    for (const double a : {0.25, 0.75}) {
      Vec3 dir;
      if (!dst.to_direction(Vec2(i + a, j + b), dir)) return -1;
      const Vec2 p = src.to_image(rotate ? apply(dst_to_src, dir) : dir);
      if (std::floor(p.x) != si || std::floor(p.y) != sj) return -1;
      const bool right = offset_is(p.x, 0.75), lower = offset_is(p.y, 0.75);
      if (!(right || offset_is(p.x, 0.25)) || !(lower || offset_is(p.y, 0.25))) return -1;
      seen |= 1u << (int(right) + 2 * int(lower));
    }
  if (seen != 0xFu) return -1;
  return static_cast<std::ptrdiff_t>(sj) * src.width() + si;
}

void apply_texel_copies(const Image& src, const TexelCopies& copies, const OutputLayout& o, Image& out) {
  const int C = src.channels, Co = out.channels;
  for (const auto& [t, s] : copies) {
    std::copy_n(src.pixels.data() + s * C, C, out.pixels.data() + t * Co);
    if (o.add_coverage) out.pixels[t * Co + o.alpha] = 1.0f;
  }
}

Image copy_same_grid(const Image& src, const Parameterization& param, const OutputLayout& o) {
  Image out = make_output(src, param, o);
  const int C = src.channels, Co = out.channels;
  tbb::parallel_for(0, src.height, [&](int j) {
    for (int i = 0; i < src.width; ++i) {
      const std::size_t t = static_cast<std::size_t>(j) * src.width + i;
      // A texel holds data exactly where its solid angle is positive (blank cells, outside a disk: none); like
      // every other path, texels without data stay 0 with coverage 0.
      if (o.add_coverage && !(param.texel_solid_angle(i, j) > 0.0)) continue;
      std::copy_n(src.pixels.data() + t * C, C, out.pixels.data() + t * Co);
      if (o.add_coverage) out.pixels[t * Co + o.alpha] = 1.0f;
    }
  });
  return out;
}

namespace {

/// Row j's power per channel (sum of omega x value over finite values, in column order), its largest value per
/// channel (+inf included, NaN never) and its largest solid angle. The sums live in locals, not in the tables they
/// end up in (which the compiler must assume the solid angle's store can overwrite): the same additions in the same
/// order, without a round trip through memory for each. kC: the channel count (1 to 4).
template <int kC>
void scan_row(const Image& img, const SolidAngleTable& omega, int j, double* row_power, double* row_peak,
              double& row_omega) {
  constexpr int C = kC;
  double power[kC] = {}, peak[kC] = {};
  double largest = 0.0;
  const float* px = img.at(0, j);
  for (int i = 0; i < img.width; ++i, px += C) {
    const double w = omega(i, j);
    if (w <= 0.0) continue;
    largest = std::max(largest, w);
    for (int c = 0; c < C; ++c) {
      if (std::isfinite(px[c])) power[c] += w * px[c];
      if (px[c] > peak[c]) peak[c] = px[c];
    }
  }
  std::copy_n(power, C, row_power);
  std::copy_n(peak, C, row_peak);
  row_omega = largest;
}

}  // namespace

std::vector<std::size_t> find_hot_texels(const Image& img, const SolidAngleTable& omega, double fraction,
                                         double contrast) {
  const int C = img.channels;
  // One pass over the image for the power (as total_power sums it) and, per row, the largest value of each channel
  // and the largest solid angle: only rows whose peaks could pass both tests are searched texel by texel.
  std::vector<double> row_power(std::size_t(img.height) * C, 0.0), row_peak(row_power.size(), 0.0);
  std::vector<double> row_omega(img.height, 0.0);
  tbb::parallel_for(0, img.height, [&](int j) {
    double* power = row_power.data() + std::size_t(j) * C;
    double* peak = row_peak.data() + std::size_t(j) * C;
    switch (C) {
      case 1:
        return scan_row<1>(img, omega, j, power, peak, row_omega[j]);
      case 2:
        return scan_row<2>(img, omega, j, power, peak, row_omega[j]);
      case 3:
        return scan_row<3>(img, omega, j, power, peak, row_omega[j]);
      case 4:
        return scan_row<4>(img, omega, j, power, peak, row_omega[j]);
      default:
        break;
    }
    for (int i = 0; i < img.width; ++i) {
      const double w = omega(i, j);
      if (w <= 0.0) continue;
      row_omega[j] = std::max(row_omega[j], w);
      const float* px = img.at(i, j);
      for (int c = 0; c < C; ++c) {
        if (std::isfinite(px[c])) power[c] += w * px[c];
        if (px[c] > peak[c]) peak[c] = px[c];  // +inf included, NaN never
      }
    }
  });
  std::vector<double> power(C, 0.0);
  for (int j = 0; j < img.height; ++j)
    for (int c = 0; c < C; ++c) power[c] += row_power[std::size_t(j) * C + c];
  const auto is_hot = [&](const float* px, double w) {
    for (int c = 0; c < C; ++c) {
      if (c == img.alpha_channel || power[c] <= 0.0) continue;
      // Bright relative to the mean radiance power / (4 pi), and a real share of the power.
      if (px[c] * kFourPi > contrast * power[c] && px[c] * w > fraction * power[c]) return true;
    }
    return false;
  };
  std::vector<std::vector<std::size_t>> per_row(img.height);
  tbb::parallel_for(0, img.height, [&](int j) {
    std::vector<float> peak(row_peak.begin() + std::size_t(j) * C, row_peak.begin() + std::size_t(j + 1) * C);
    if (!is_hot(peak.data(), row_omega[j])) return;  // no texel of the row can pass
    for (int i = 0; i < img.width; ++i)
      if (is_hot(img.at(i, j), omega(i, j))) per_row[j].push_back(static_cast<std::size_t>(j) * img.width + i);
  });
  std::vector<std::size_t> hot;
  for (const auto& row : per_row) hot.insert(hot.end(), row.begin(), row.end());
  return hot;
}

void splat_hot_texels(const MapRef& s, const std::vector<std::size_t>& hot, const SolidAngleTable& src_omega,
                      const Parameterization& dst, const SolidAngleTable& dst_omega, const Mat3& dst_to_src,
                      Image& out) {
  if (hot.empty()) return;
  const Image& img = s.image;
  const Parameterization& sp = s.param;
  const int C = img.channels, W = img.width;
  const Mat3 src_to_dst = transposed(dst_to_src);
  std::vector<std::vector<std::pair<std::size_t, double>>> contributions(hot.size());  // (output texel, omega)
  tbb::parallel_for(std::size_t(0), hot.size(), [&](std::size_t h) {
    const int si = static_cast<int>(hot[h] % W), sj = static_cast<int>(hot[h] / W);
    const double omega_s = src_omega(si, sj);
    Vec3 centre_dir;
    if (!sp.to_direction(Vec2(si + 0.5, sj + 0.5), centre_dir)) centre_dir = Vec3(0, 0, 1);
    const Vec2 pc = dst.to_image(apply(src_to_dst, centre_dir));
    // (A camera view maps directions it does not see outside its image: clamp into it for this size estimate.)
    const int ci = std::clamp(static_cast<int>(std::clamp(pc.x, 0.0, double(dst.width()))), 0, dst.width() - 1);
    const int cj = std::clamp(static_cast<int>(std::clamp(pc.y, 0.0, double(dst.height()))), 0, dst.height() - 1);
    const double omega_t = std::max(dst_omega(ci, cj), 1e-300);
    // Clamped before the cast: omega_t is tiny where the estimate lands on a texel without data (a fisheye's corner).
    const int m = static_cast<int>(std::clamp(std::ceil(4.0 * std::sqrt(omega_s / omega_t)), 2.0, 64.0));
    auto& list = contributions[h];
    for (int b = 0; b < m; ++b) {
      for (int a = 0; a < m; ++a) {
        const double x0 = si + double(a) / m, y0 = sj + double(b) / m;
        const double w = sp.solid_angle(x0, y0, x0 + 1.0 / m, y0 + 1.0 / m);
        if (w <= 0.0) continue;
        Vec3 d;
        if (!sp.to_direction(Vec2(x0 + 0.5 / m, y0 + 0.5 / m), d)) d = centre_dir;
        const Vec2 q = dst.to_image(apply(src_to_dst, d));
        // A camera view maps what it does not see outside its image: that flux is not in the view.
        if (q.x < 0.0 || q.y < 0.0 || q.x > dst.width() || q.y > dst.height()) continue;
        const int ti = std::clamp(static_cast<int>(q.x), 0, dst.width() - 1);
        const int tj = std::clamp(static_cast<int>(q.y), 0, dst.height() - 1);
        list.emplace_back(static_cast<std::size_t>(tj) * dst.width() + ti, w);
      }
    }
  });
  // Serial accumulation in a fixed order keeps the result independent of the thread count.
  const int Co = out.channels;
  for (std::size_t h = 0; h < hot.size(); ++h) {
    const float* src_px = img.pixels.data() + hot[h] * C;
    for (const auto& [t, w] : contributions[h]) {
      const int ti = static_cast<int>(t % dst.width()), tj = static_cast<int>(t / dst.width());
      const double omega_t = dst_omega(ti, tj);
      if (omega_t <= 0.0) continue;
      float* px = out.pixels.data() + t * Co;
      for (int c = 0; c < C; ++c)
        if (c != img.alpha_channel) px[c] = static_cast<float>(px[c] + src_px[c] * (w / omega_t));
    }
  }
}

namespace {

/// Replaces each group of twin texels (indices into the image) by their solid-angle weighted mean.
void average_twins(const std::vector<std::vector<std::size_t>>& groups, const SolidAngleTable& omega, Image& out) {
  const int C = out.channels, W = out.width;
  std::vector<double> mean(static_cast<std::size_t>(C));
  for (const auto& group : groups) {
    if (group.size() < 2) continue;
    std::fill(mean.begin(), mean.end(), 0.0);
    double weight = 0.0;
    for (std::size_t t : group) {
      const double w = omega(int(t % W), int(t / W));
      weight += w;
      for (int c = 0; c < C; ++c) mean[c] += w * out.pixels[t * C + c];
    }
    if (!(weight > 0.0)) continue;
    for (std::size_t t : group)
      for (int c = 0; c < C; ++c) out.pixels[t * C + c] = static_cast<float>(mean[c] / weight);
  }
}

}  // namespace

void merge_twin_texels(const Parameterization& dst, const SolidAngleTable& omega, Image& out) {
  average_twins(dst.twin_texels(), omega, out);
}

}  // namespace envkit::detail
