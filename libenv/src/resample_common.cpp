#include "resample_common.h"

#include <envkit/cubemap.h>
#include <envkit/latlong.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>

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
    const double omega_t = std::max(
        dst_omega(std::min(int(pc.x), dst.width() - 1), std::min(int(pc.y), dst.height() - 1)), 1e-300);
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
  std::vector<std::vector<std::size_t>> groups;
  const std::size_t W = static_cast<std::size_t>(out.width);
  if (const auto* ll = dynamic_cast<const LatLongMap*>(&dst); ll && ll->grid() == TexelGrid::Corner) {
    if (out.width < 2) return;
    for (std::size_t j = 0; j < std::size_t(out.height); ++j) groups.push_back({j * W, j * W + W - 1});
  } else if (const auto* cube = dynamic_cast<const CubeMap*>(&dst); cube && cube->grid() == TexelGrid::Corner) {
    const int N = cube->face_size();
    if (N < 2) return;
    // Edge texel centres lie on the cube's edges: the point where the centre's direction meets the cube has
    // coordinates on the grid -1 + 2k / (N - 1), and those integer k name the texel's twins exactly.
    std::map<std::uint64_t, std::vector<std::size_t>> by_point;
    for (int f = 0; f < 6; ++f) {
      const CubeFace& face = cube->face(f);
      for (int j = 0; j < N; ++j)
        for (int i = 0; i < N; ++i) {
          if (i != 0 && i != N - 1 && j != 0 && j != N - 1) continue;
          const int x = face.origin_x + i, y = face.origin_y + j;
          Vec3 d;
          if (!cube->to_direction(Vec2(x + 0.5, y + 0.5), d)) continue;
          const double m = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
          if (!(m > 0.0)) continue;
          std::uint64_t key = 0;
          for (double p : {d.x / m, d.y / m, d.z / m})
            key = key * std::uint64_t(N) + std::uint64_t(std::clamp(std::llround((p + 1.0) * 0.5 * (N - 1)), 0LL,
                                                                       static_cast<long long>(N - 1)));
          by_point[key].push_back(std::size_t(y) * W + std::size_t(x));
        }
    }
    for (auto& [key, group] : by_point) groups.push_back(std::move(group));
  } else {
    return;
  }
  average_twins(groups, omega, out);
}

}  // namespace envkit::detail
