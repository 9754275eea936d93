// Split-sum specular shading from a GGX chain and a DFG LUT, filtered like a GPU (see split_sum.h).
#include <envkit/core/error.h>
#include <envkit/ibl/split_sum.h>
#include <envkit/maps/cubemap.h>
#include <envkit/resample/filter.h>

#include <algorithm>
#include <cmath>

namespace envkit {

SplitSumIbl::SplitSumIbl(std::vector<Image> cube_levels, std::vector<double> level_roughness, Image lut)
    : levels_(std::move(cube_levels)), roughness_(std::move(level_roughness)), lut_(std::move(lut)) {
  if (levels_.empty() || levels_.size() != roughness_.size())
    throw Error("split sum: " + std::to_string(levels_.size()) + " levels but " + std::to_string(roughness_.size()) +
                " roughness values");
  if (lut_.empty() || lut_.channels < 2) throw Error("split sum: the DFG LUT needs at least 2 channels");
  for (std::size_t m = 0; m < levels_.size(); ++m) {
    const Image& l = levels_[m];
    const int n = l.width;
    if (n < 1 || l.height != 6 * n || l.channels < 3)
      throw Error("split sum: level " + std::to_string(m) + " is not a 3-channel N x 6N cube strip");
    if (m > 0 && n != std::max(1, levels_[0].width >> m))
      throw Error("split sum: level " + std::to_string(m) + " does not halve the previous one");
    params_.push_back(std::make_unique<CubeMap>(n, CubeLayout::VerticalStrip, CubeBasis::GL, TexelGrid::Centre));
    sources_.push_back(std::make_unique<TexelSource>(levels_[m], *params_.back()));
  }
}

SplitSumIbl::~SplitSumIbl() = default;

double SplitSumIbl::lod(double roughness) const {
  const int last = int(roughness_.size()) - 1;
  if (last <= 0 || roughness <= roughness_[0]) return 0.0;
  for (int m = 0; m < last; ++m) {
    const double r0 = roughness_[m], r1 = roughness_[m + 1];
    if (roughness <= r1) return r1 > r0 ? m + (roughness - r0) / (r1 - r0) : m;
  }
  return last;
}

Vec3 SplitSumIbl::radiance(const Vec3& dir, double lod) const {
  lod = std::clamp(lod, 0.0, double(levels_.size() - 1));
  const int m0 = int(std::floor(lod));
  const int m1 = std::min(m0 + 1, int(levels_.size()) - 1);
  const double t = lod - m0;
  Vec3 sum(0.0);
  for (int k = 0; k < 2; ++k) {
    const int m = k == 0 ? m0 : m1;
    const double w = k == 0 ? 1.0 - t : t;
    if (w == 0.0) continue;
    float px[4] = {0, 0, 0, 0};
    sources_[m]->sample(params_[m]->to_image(dir), Filter::Bilinear, px);
    sum += w * Vec3(px[0], px[1], px[2]);
  }
  return sum;
}

void SplitSumIbl::dfg(double n_dot_v, double roughness, double& a, double& b) const {
  const double x = std::clamp(n_dot_v * lut_.width - 0.5, 0.0, lut_.width - 1.0);
  const double y = std::clamp(roughness * lut_.height - 0.5, 0.0, lut_.height - 1.0);
  const int x0 = int(x), y0 = int(y);
  const int x1 = std::min(x0 + 1, lut_.width - 1), y1 = std::min(y0 + 1, lut_.height - 1);
  const double fx = x - x0, fy = y - y0;
  auto at = [&](int c) {
    return (1 - fy) * ((1 - fx) * lut_.at(x0, y0, c) + fx * lut_.at(x1, y0, c)) +
           fy * ((1 - fx) * lut_.at(x0, y1, c) + fx * lut_.at(x1, y1, c));
  };
  a = at(0);
  b = at(1);
}

Vec3 SplitSumIbl::specular(const Vec3& n, const Vec3& v, double roughness, const Vec3& f0) const {
  const double nv = std::clamp(n ^ v, 0.0, 1.0);
  const Vec3 r = 2.0 * (n ^ v) * n - v;
  double a = 0.0, b = 0.0;
  dfg(nv, roughness, a, b);
  const Vec3 l = radiance(r, lod(roughness));
  return Vec3(l.x * (f0.x * a + b), l.y * (f0.y * a + b), l.z * (f0.z * a + b));
}

}  // namespace envkit
