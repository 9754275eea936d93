#include <envkit/sampling/distribution_sparse.h>

#include <algorithm>
#include <cmath>

namespace envkit {

SparseDistribution2D::SparseDistribution2D(int width, int height, std::span<const std::uint64_t> texels,
                                           std::span<const float> weights)
    : StoredDistribution2D(width, height) {
  if (texels.size() != weights.size())
    throw Error("sparse distribution: " + std::to_string(texels.size()) + " texels but " +
                std::to_string(weights.size()) + " weights");
  const std::uint64_t grid = std::uint64_t(width) * std::uint64_t(height);
  double total = 0.0;
  for (std::size_t k = 0; k < texels.size(); ++k) {
    if (texels[k] >= grid || (k > 0 && texels[k] <= texels[k - 1]))
      throw Error("sparse distribution: texel indices must be ascending and inside the " + std::to_string(width) + "x" +
                  std::to_string(height) + " grid");
    const float w = sampling::sanitize_weight(weights[k]);
    if (w > 0.0f) {
      texels_.push_back(texels[k]);
      total += w;
    }
  }
  if (!(total > 0.0)) throw Error("sparse distribution: no texel has a positive weight");
  cdf_.reserve(texels_.size() + 1);
  pdf_uv_.reserve(texels_.size());
  cdf_.push_back(0.0);
  double running = 0.0;
  const double area = double(width) * double(height);
  for (std::size_t k = 0, j = 0; k < texels.size(); ++k) {
    const float w = sampling::sanitize_weight(weights[k]);
    if (!(w > 0.0f)) continue;
    running += w;
    cdf_.push_back(j + 1 == texels_.size() ? 1.0 : running / total);
    pdf_uv_.push_back(w / total * area);
    ++j;
  }
  integral_ = total / area;
}

SparseDistribution2D::SparseDistribution2D(BlobReader& in) : StoredDistribution2D(in) {
  texels_ = in.array<std::uint64_t>();
  cdf_ = in.array<double>(texels_.size() + 1);
  pdf_uv_ = in.array<double>(texels_.size());
  in.finish();
  validate(in.context());
}

// What a file says is checked against itself, so that what sample() draws is what pdf() reports.
void SparseDistribution2D::validate(const std::string& context) const {
  const auto refuse = [&](const std::string& what) { throw Error(context + ": invalid sparse table (" + what + ")"); };
  const std::uint64_t grid = std::uint64_t(width_) * std::uint64_t(height_);
  const double area = double(grid);
  if (texels_.empty()) refuse("no texels");
  if (cdf_.front() != 0.0 || cdf_.back() != 1.0) refuse("cumulative probabilities must run from 0 to 1");
  for (std::size_t k = 0; k < texels_.size(); ++k) {
    if (texels_[k] >= grid || (k > 0 && texels_[k] <= texels_[k - 1])) refuse("texel indices");
    const double p = cdf_[k + 1] - cdf_[k];
    // Steps are differences of cumulative sums near 1: a tiny texel's step carries their absolute rounding.
    if (!(p > 0.0) || !(std::abs(pdf_uv_[k] / area - p) <= 1e-6 * p + 1e-14))
      refuse("a texel's density disagrees with its cumulative step");
  }
}

std::ptrdiff_t SparseDistribution2D::find(int x, int y) const {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return -1;
  const std::uint64_t t = std::uint64_t(y) * std::uint64_t(width_) + std::uint64_t(x);
  const auto it = std::lower_bound(texels_.begin(), texels_.end(), t);
  return it != texels_.end() && *it == t ? it - texels_.begin() : -1;
}

TexelSample SparseDistribution2D::sample_texel(Vec2 u) const {
  const double ux = sampling::clamp_decision(u.x);
  // The texel whose step [cdf_k, cdf_k+1) holds ux: every step is positive, so k is unique.
  const std::size_t k = std::min<std::size_t>(
      std::size_t(std::upper_bound(cdf_.begin() + 1, cdf_.end(), ux) - (cdf_.begin() + 1)), texels_.size() - 1);
  TexelSample t;
  t.fx = sampling::clamp_offset((ux - cdf_[k]) / (cdf_[k + 1] - cdf_[k]));
  t.fy = sampling::clamp_offset(u.y);
  t.pdf = pdf_uv_[k];
  t.x = int(texels_[k] % std::uint64_t(width_));
  t.y = int(texels_[k] / std::uint64_t(width_));
  return t;
}

DistributionSample SparseDistribution2D::sample(Vec2 u) const {
  const TexelSample t = sample_texel(u);
  return {Vec2((t.x + t.fx) / width_, (t.y + t.fy) / height_), t.pdf, t.x, t.y};
}

double SparseDistribution2D::pdf(Vec2 uv) const {
  if (!sampling::in_unit_square(uv)) return 0.0;
  const std::ptrdiff_t k = find(sampling::texel_index(uv.x, width_), sampling::texel_index(uv.y, height_));
  return k < 0 ? 0.0 : pdf_uv_[std::size_t(k)];
}

double SparseDistribution2D::texel_probability(int x, int y) const {
  const std::ptrdiff_t k = find(x, y);
  return k < 0 ? 0.0 : cdf_[std::size_t(k) + 1] - cdf_[std::size_t(k)];
}

Vec2 SparseDistribution2D::invert(Vec2 uv) const {
  const double cx = std::isfinite(uv.x) ? std::clamp(uv.x, 0.0, 1.0) : 0.0;
  const double cy = std::isfinite(uv.y) ? std::clamp(uv.y, 0.0, 1.0) : 0.0;
  const int x = sampling::texel_index(cx, width_), y = sampling::texel_index(cy, height_);
  const std::ptrdiff_t k = find(x, y);
  if (k < 0) return Vec2(0.0, 0.0);  // unlit texel: no u reaches it
  const std::size_t i = std::size_t(k);
  const double fx = sampling::clamp_offset(cx * width_ - x), fy = sampling::clamp_offset(cy * height_ - y);
  return Vec2(sampling::clamp_decision(cdf_[i] + fx * (cdf_[i + 1] - cdf_[i])), fy);
}

std::size_t SparseDistribution2D::bytes() const {
  return texels_.size() * sizeof(std::uint64_t) + (cdf_.size() + pdf_uv_.size()) * sizeof(double);
}

void SparseDistribution2D::save(BlobWriter& out) const {
  save_base(out);
  out.array(texels_);
  out.array(cdf_);
  out.array(pdf_uv_);
}

}  // namespace envkit
