#include <envkit/error.h>
#include <envkit/resample.h>
#include <envkit/solid_angle_table.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>

namespace envkit {

namespace {

// Reports progress in steps of about 1% from whichever worker crosses a step.
class ProgressCounter {
 public:
  ProgressCounter(const ProgressFn& fn, std::size_t total) : fn_(fn), total_(std::max<std::size_t>(total, 1)) {}
  void add(std::size_t n) {
    if (!fn_) return;
    const std::size_t before = done_.fetch_add(n);
    const std::size_t step = std::max<std::size_t>(total_ / 100, 1);
    if ((before + n) / step != before / step) {
      std::lock_guard<std::mutex> lock(mutex_);
      fn_(std::min(1.0, double(before + n) / double(total_)));
    }
  }

 private:
  const ProgressFn& fn_;
  std::size_t total_;
  std::atomic<std::size_t> done_{0};
  std::mutex mutex_;
};

struct OutputLayout {
  int channels = 0;       // output channels
  int alpha = -1;         // output alpha index
  bool add_coverage = false;
};

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

// Source position seen by an output direction; false when it falls outside the source image (cropped balls).
bool source_position(const Parameterization& src, const Mat3& dst_to_src, const Vec3& dir, Vec2& p) {
  p = src.to_image(apply(dst_to_src, dir));
  return p.x >= 0.0 && p.y >= 0.0 && p.x <= src.width() && p.y <= src.height();
}

// Sub-samples per axis for output texel (i, j): enough to put `supersampling` samples across each source
// texel of its footprint. The footprint is measured by the angle its corners span, which also catches the
// long thin texels near a mirror ball's rim or a lat-long's poles that an area ratio would miss.
int subsamples_per_axis(const Parameterization& dst, const Parameterization& src, const SolidAngleTable& src_omega,
                        const Mat3& dst_to_src, int i, int j, const ResampleOptions& opt) {
  Vec3 centre;
  Vec2 p;
  if (!dst.to_direction(Vec2(i + 0.5, j + 0.5), centre) || !source_position(src, dst_to_src, centre, p))
    return opt.max_subsamples;
  const double inset = 1e-6;  // corners just inside the texel, so they belong to its face/disk
  const Vec2 corners[4] = {Vec2(i + inset, j + inset), Vec2(i + 1 - inset, j + inset), Vec2(i + inset, j + 1 - inset),
                           Vec2(i + 1 - inset, j + 1 - inset)};
  double extent = 0.0;
  for (const Vec2& c : corners) {
    Vec3 d;
    if (!dst.to_direction(c, d)) return opt.max_subsamples;  // straddles a rim: sample it finely
    extent = std::max(extent, (d - centre).length());  // chord: the angle to within 1% below 0.3 rad, no atan2
  }
  const int si = std::clamp(static_cast<int>(p.x), 0, src.width() - 1);
  const int sj = std::clamp(static_cast<int>(p.y), 0, src.height() - 1);
  const double source_size = std::sqrt(std::max(src_omega(si, sj), 0.0));
  if (source_size <= 0.0) return opt.max_subsamples;
  // Corner-to-centre angle is half the footprint's diagonal, about 0.7 of its side.
  const double footprint_in_texels = 2.0 * extent / std::sqrt(2.0) / source_size;
  return std::clamp(static_cast<int>(std::ceil(opt.supersampling * footprint_in_texels - 1e-9)), 1, opt.max_subsamples);
}

Image resample_point(const MapRef& s, const TexelSource& source, const Parameterization& dst, const Mat3& dst_to_src,
                     const ResampleOptions& opt) {
  const OutputLayout o = output_layout(s.image, source);
  Image out = make_output(s.image, dst, o);
  const int C = s.image.channels;
  ProgressCounter progress(opt.progress, static_cast<std::size_t>(dst.height()));
  tbb::parallel_for(0, dst.height(), [&](int j) {
    std::vector<float> value(C);
    for (int i = 0; i < dst.width(); ++i) {
      float* px = out.at(i, j);
      Vec3 dir;
      Vec2 p, q;
      if (!dst.covered_point(i, j, q) || !dst.to_direction(q, dir) || !source_position(s.param, dst_to_src, dir, p))
        continue;
      const bool ok = source.sample(p, opt.filter, value.data());
      for (int c = 0; c < C; ++c) px[c] = value[c];
      if (o.add_coverage) px[o.alpha] = ok ? 1.0f : 0.0f;
    }
    progress.add(1);
  });
  return out;
}

// Texels that are both far brighter than the mean and carry a real share of a channel's power.
std::vector<std::size_t> find_hot_texels(const Image& img, const SolidAngleTable& omega, double fraction,
                                         double contrast, const std::vector<double>& power) {
  const int C = img.channels;
  std::vector<std::vector<std::size_t>> per_row(img.height);
  tbb::parallel_for(0, img.height, [&](int j) {
    for (int i = 0; i < img.width; ++i) {
      const double w = omega(i, j);
      const float* px = img.at(i, j);
      for (int c = 0; c < C; ++c) {
        if (c == img.alpha_channel || power[c] <= 0.0) continue;
        // Bright relative to the mean radiance power / (4 pi), and a real share of the power.
        if (px[c] * kFourPi > contrast * power[c] && px[c] * w > fraction * power[c]) {
          per_row[j].push_back(static_cast<std::size_t>(j) * img.width + i);
          break;
        }
      }
    }
  });
  std::vector<std::size_t> hot;
  for (const auto& row : per_row) hot.insert(hot.end(), row.begin(), row.end());
  return hot;
}

Image resample_area(const MapRef& s, const TexelSource& full_source, const Parameterization& dst,
                    const Mat3& dst_to_src, const ResampleOptions& opt) {
  const Image& img = s.image;
  const Parameterization& sp = s.param;
  const int C = img.channels, W = img.width;
  const OutputLayout o = output_layout(img, full_source);
  Image out = make_output(img, dst, o);
  const SolidAngleTable src_omega(sp), dst_omega(dst);
  const std::vector<double> power = total_power(img, sp);

  // 1. Split off the hot texels: they are splatted exactly below, the cold remainder is gathered.
  const std::vector<std::size_t> hot = find_hot_texels(img, src_omega, opt.hot_fraction, opt.hot_contrast, power);
  Image cold_copy;
  const Image* cold = &img;
  if (!hot.empty()) {
    cold_copy = img;
    for (std::size_t t : hot)
      for (int c = 0; c < C; ++c)
        if (c != img.alpha_channel) cold_copy.pixels[t * C + c] = 0.0f;
    cold = &cold_copy;
  }
  const TexelSource source(*cold, sp);

  // 2. Gather the cold part: supersample each output texel, weights = exact sub-cell solid angles.
  ProgressCounter progress(opt.progress, static_cast<std::size_t>(dst.height()) + (hot.empty() ? 0 : dst.height() / 10));
  tbb::parallel_for(0, dst.height(), [&](int j) {
    std::vector<double> sum(C);
    Tap taps[16];
    for (int i = 0; i < dst.width(); ++i) {
      const double omega_t = dst_omega(i, j);
      if (omega_t <= 0.0) continue;
      Vec3 dir;
      Vec2 p;
      const int n = subsamples_per_axis(dst, sp, src_omega, dst_to_src, i, j, opt);
      std::fill(sum.begin(), sum.end(), 0.0);
      double covered_weight = 0.0, total_weight = 0.0;
      for (int b = 0; b < n; ++b) {
        for (int a = 0; a < n; ++a) {
          const double x0 = i + double(a) / n, y0 = j + double(b) / n;
          // Weights need only be proportional to each sub-cell's solid angle: the result is normalised below.
          const double w = n == 1 ? omega_t : dst.solid_angle_density(Vec2(x0 + 0.5 / n, y0 + 0.5 / n));
          if (w <= 0.0) continue;
          total_weight += w;
          if (!dst.to_direction(Vec2(x0 + 0.5 / n, y0 + 0.5 / n), dir) || !source_position(sp, dst_to_src, dir, p))
            continue;
          const int k = source.taps(p, Filter::Bilinear, taps);
          if (k == 0) continue;
          covered_weight += w;
          for (int t = 0; t < k; ++t) {
            const float* px = cold->pixels.data() + taps[t].index * C;
            const double tw = w * taps[t].weight;
            for (int c = 0; c < C; ++c) sum[c] += tw * px[c];
          }
        }
      }
      // A sliver of data (a rim texel whose sub-samples all fell outside the disk): sample its covered point.
      Vec2 q;
      if (covered_weight == 0.0 && dst.covered_point(i, j, q) && dst.to_direction(q, dir) &&
          source_position(sp, dst_to_src, dir, p)) {
        const int k = source.taps(p, Filter::Bilinear, taps);
        for (int t = 0; t < k; ++t) {
          const float* px = cold->pixels.data() + taps[t].index * C;
          for (int c = 0; c < C; ++c) sum[c] += taps[t].weight * px[c];
        }
        if (k > 0) covered_weight = total_weight = 1.0;
      }
      float* px = out.at(i, j);
      if (covered_weight > 0.0)
        for (int c = 0; c < C; ++c) px[c] = static_cast<float>(sum[c] / covered_weight);
      if (o.add_coverage) px[o.alpha] = static_cast<float>(covered_weight / std::max(total_weight, 1e-300));
      else if (o.alpha >= 0 && covered_weight > 0.0)
        px[o.alpha] = static_cast<float>(sum[o.alpha] / total_weight);  // source alpha, fading where uncovered
    }
    progress.add(1);
  });

  // 3. Splat the hot texels: flux L x (exact sub-cell solid angle) into the output texel that sees each sub-cell.
  if (!hot.empty()) {
    const Mat3 src_to_dst = transposed(dst_to_src);
    std::vector<std::vector<std::pair<std::size_t, double>>> contributions(hot.size());  // (output texel, omega)
    tbb::parallel_for(std::size_t(0), hot.size(), [&](std::size_t h) {
      const int si = static_cast<int>(hot[h] % W), sj = static_cast<int>(hot[h] / W);
      const double omega_s = src_omega(si, sj);
      Vec3 centre_dir;
      if (!sp.to_direction(Vec2(si + 0.5, sj + 0.5), centre_dir)) centre_dir = Vec3(0, 0, 1);
      const Vec2 pc = dst.to_image(apply(src_to_dst, centre_dir));
      const double omega_t = std::max(dst_omega(std::min(int(pc.x), dst.width() - 1), std::min(int(pc.y), dst.height() - 1)), 1e-300);
      const int m = std::clamp(static_cast<int>(std::ceil(4.0 * std::sqrt(omega_s / omega_t))), 2, 64);
      auto& list = contributions[h];
      for (int b = 0; b < m; ++b) {
        for (int a = 0; a < m; ++a) {
          const double x0 = si + double(a) / m, y0 = sj + double(b) / m;
          const double w = sp.solid_angle(x0, y0, x0 + 1.0 / m, y0 + 1.0 / m);
          if (w <= 0.0) continue;
          Vec3 d;
          if (!sp.to_direction(Vec2(x0 + 0.5 / m, y0 + 0.5 / m), d)) d = centre_dir;
          const Vec2 q = dst.to_image(apply(src_to_dst, d));
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
    progress.add(static_cast<std::size_t>(dst.height() / 10));
  }
  return out;
}

}  // namespace

std::vector<double> total_power(const Image& image, const Parameterization& param) {
  const SolidAngleTable omega(param);
  const int C = image.channels;
  std::vector<std::vector<double>> rows(image.height, std::vector<double>(C, 0.0));
  tbb::parallel_for(0, image.height, [&](int j) {
    for (int i = 0; i < image.width; ++i) {
      const double w = omega(i, j);
      if (w <= 0.0) continue;
      const float* px = image.at(i, j);
      for (int c = 0; c < C; ++c)
        if (std::isfinite(px[c])) rows[j][c] += w * px[c];
    }
  });
  std::vector<double> power(C, 0.0);
  for (const auto& r : rows)
    for (int c = 0; c < C; ++c) power[c] += r[c];
  return power;
}

Image resample(const MapRef& src, const Parameterization& dst, const Mat3& dst_to_world, const ResampleOptions& opt) {
  if (src.image.empty()) throw Error("cannot resample an empty image");
  const TexelSource source(src.image, src.param);
  const Mat3 dst_to_src = compose(transposed(src.to_world), dst_to_world);
  if (opt.filter == Filter::Area) return resample_area(src, source, dst, dst_to_src, opt);
  return resample_point(src, source, dst, dst_to_src, opt);
}

}  // namespace envkit
