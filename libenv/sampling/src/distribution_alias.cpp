#include <envkit/sampling/distribution_alias.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace envkit {

namespace {

using detail::alias_candidate;
using detail::alias_keep;
using sampling::clamp_decision;
using sampling::clamp_offset;
using sampling::sanitize_weight;

constexpr std::size_t kParallelTexels = std::size_t(1) << 16;

/// Two-sided storage of a keep probability q (see AliasBin::keep): +q for q <= 1/2, -(1 - q) above, so that both
/// q and the donation 1 - q keep float relative precision. -0 means "always keep", +0 "never keep".
/// `donation` must be 1 - q computed exactly (it is, in double, for q >= 1/2).
float encode_keep(double q, double donation) {
  return q <= 0.5 ? static_cast<float>(q) : -static_cast<float>(donation);
}
double keep_share(float stored) { return std::signbit(stored) ? 1.0 + double(stored) : double(stored); }
double donated_share(float stored) { return std::signbit(stored) ? -double(stored) : 1.0 - double(stored); }
constexpr float kAlwaysKeep = -0.0f;
constexpr float kNeverKeep = 0.0f;

/// Vose's alias method in double. weight(i) >= 0 with sum `sum` > 0 (the caller handles the uniform case).
/// Writes keep/alias of bins[0..n). scaled and work are scratch arrays of n entries.
/// Deterministic: the work lists are processed in a fixed order.
template <class Bin, class WeightFn>
void build_vose(int n, const WeightFn& weight, double sum, Bin* bins, double* scaled, std::uint32_t* work) {
  // Small items stack up from the front of `work`, large ones from the back; together never more than n.
  int n_small = 0, n_large = 0;
  std::uint32_t some_positive = 0;
  const double scale = double(n) / sum;
  for (int i = 0; i < n; ++i) {
    const double w = weight(i);
    scaled[i] = w * scale;
    if (w > 0.0) some_positive = std::uint32_t(i);
    if (scaled[i] < 1.0)
      work[n_small++] = std::uint32_t(i);
    else
      work[n - 1 - n_large++] = std::uint32_t(i);
  }
  while (n_small > 0 && n_large > 0) {
    const std::uint32_t s = work[--n_small];
    const std::uint32_t l = work[n - n_large];
    const double q = std::clamp(scaled[s], 0.0, 1.0), donation = 1.0 - q;
    float keep = encode_keep(q, donation);
    // A positive bin must not round to "never keep" (unreachable while pdf says otherwise).
    if (keep == 0.0f && !std::signbit(keep) && weight(int(s)) > 0.0) keep = FLT_TRUE_MIN;
    bins[s].keep = keep;
    bins[s].alias = l;
    scaled[l] -= donation;
    if (scaled[l] < 1.0) {
      --n_large;
      work[n_small++] = l;
    }
  }
  while (n_large > 0) {
    const std::uint32_t l = work[n - n_large--];
    bins[l].keep = kAlwaysKeep;
    bins[l].alias = l;
  }
  // Leftover small items are ~1 up to rounding, except that a zero-weight bin must never be kept.
  while (n_small > 0) {
    const std::uint32_t s = work[--n_small];
    const bool positive = weight(int(s)) > 0.0;
    bins[s].keep = positive ? kAlwaysKeep : kNeverKeep;
    bins[s].alias = positive ? s : some_positive;
  }
}

template <class Bin>
void make_uniform(int n, Bin* bins) {
  for (int i = 0; i < n; ++i) {
    bins[i].keep = kAlwaysKeep;
    bins[i].alias = std::uint32_t(i);
  }
}

/// Copies each bin's alias weight from the bin it names (after the weights and aliases are final).
void fill_alias_weights(AliasBin* bins, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) bins[i].alias_weight = bins[bins[i].alias].weight;
}

/// Probability an alias step (detail::alias_keep) returns bin i: its own keep share plus every donation aimed at
/// it, over n. O(n).
template <class Bin>
double alias_probability(const Bin* bins, int n, int i) {
  double p = keep_share(bins[i].keep);
  for (int j = 0; j < n; ++j)
    if (bins[j].alias == std::uint32_t(i)) p += donated_share(bins[j].keep);
  return p / n;
}

/// Drawn probability of every bin (times n) in one pass: the keep shares plus the donations. Invalid coins
/// (NaN, |keep| > 1/2) make the result NaN, which the caller refuses.
template <class Bin>
void drawn_shares(const Bin* bins, std::size_t n, std::vector<double>& share) {
  share.assign(n, 0.0);
  for (std::size_t j = 0; j < n; ++j) {
    const float k = bins[j].keep;
    if (!(std::abs(k) <= 0.5f)) {
      share[0] = std::numeric_limits<double>::quiet_NaN();
      return;
    }
    share[j] += keep_share(k);
    share[bins[j].alias] += donated_share(k);
  }
}

/// Restored tables are checked against what they claim: a drawn share and the share the weights give may differ
/// by float rounding of the coins (about 2^-24 per donation), not more.
bool share_matches(double drawn, double expected) { return std::abs(drawn - expected) <= 1e-4 * expected + 1e-6; }

}  // namespace

// ---------------------------------------------------------------------------------------------------------------
// AliasTable1D

AliasTable1D::AliasTable1D(std::span<const float> weights) {
  if (weights.empty() || weights.size() > std::size_t(kMaxDistributionSize))
    throw Error("AliasTable1D: need 1.." + std::to_string(kMaxDistributionSize) + " weights, got " +
                std::to_string(weights.size()));
  const int n = static_cast<int>(weights.size());
  bins_.resize(weights.size());
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    bins_[i].weight = sanitize_weight(weights[std::size_t(i)]);
    sum += bins_[i].weight;
  }
  integral_ = sum / n;
  uniform_fallback_ = !(sum > 0.0);
  if (uniform_fallback_) {
    make_uniform(n, bins_.data());
    for (AliasBin& b : bins_) b.weight = b.alias_weight = 1.0f;
    pdf_scale_ = 1.0;
    return;
  }
  std::vector<double> scaled(weights.size());
  std::vector<std::uint32_t> work(weights.size());
  build_vose(
      n, [&](int i) { return double(bins_[i].weight); }, sum, bins_.data(), scaled.data(), work.data());
  fill_alias_weights(bins_.data(), bins_.size());
  pdf_scale_ = n / sum;
}

AliasTable1D::Sample AliasTable1D::sample(double u) const {
  const int n = size();
  double coin, offset;
  const std::uint32_t candidate = alias_candidate(clamp_decision(u), n, coin);
  const AliasBin& bin = bins_[candidate];
  const bool keep = alias_keep(bin, coin, offset);
  const int i = static_cast<int>(keep ? candidate : bin.alias);
  return {(i + offset) / n, (keep ? bin.weight : bin.alias_weight) * pdf_scale_, i};
}

double AliasTable1D::pdf(double x) const {
  if (!(x >= 0.0 && x <= 1.0) || bins_.empty()) return 0.0;
  return bins_[sampling::texel_index(x, size())].weight * pdf_scale_;
}

double AliasTable1D::bin_probability(int i) const {
  if (i < 0 || i >= size()) return 0.0;
  return alias_probability(bins_.data(), size(), i);
}

// ---------------------------------------------------------------------------------------------------------------
// AliasDistribution2D

AliasDistribution2D::AliasDistribution2D(BlobReader& in) : StoredDistribution2D(in) {
  const std::size_t W = std::size_t(width_), H = std::size_t(height_);
  pdf_scale_ = in.scalar<double>();
  texels_ = in.table<AliasBin>(W * H);
  rows_ = in.table<RowBin>(H);
  in.finish();
  width_f_ = width_;
  height_f_ = height_;
  // One pass over the aliases: a corrupt index would read outside the table. (keep and alias_weight are not
  // re-checked: wrong values change probabilities, not memory safety, and the section checksums catch corruption.)
  const bool texels_ok = std::all_of(std::as_const(texels_).begin(), std::as_const(texels_).end(),
                                     [W](const AliasBin& b) { return b.alias < W; });
  const bool rows_ok = std::all_of(std::as_const(rows_).begin(), std::as_const(rows_).end(),
                                   [H](const RowBin& b) { return b.alias < H; });
  if (!texels_ok || !rows_ok) throw Error(in.context() + ": alias index out of range");
  validate(in.context());
}

// A table whose checksum matches may still hold values no bake produces (a bug elsewhere, a hand-edited file, a
// checksum recomputed over damage): every coin, weight and the pdf scale are checked against each other, so what
// is drawn is what pdf() reports. One pass over the texels, like the checksum.
void AliasDistribution2D::validate(const std::string& context) const {
  const std::size_t W = std::size_t(width_), H = std::size_t(height_);
  const auto refuse = [&](const std::string& what) { throw Error(context + ": invalid alias table (" + what + ")"); };
  std::vector<double> row_sum(H, 0.0), share;
  double total = 0.0;
  for (std::size_t y = 0; y < H; ++y) {
    const AliasBin* bins = texels_.data() + y * W;
    double sum = 0.0;
    for (std::size_t x = 0; x < W; ++x) {
      const float w = bins[x].weight;
      if (!(w >= 0.0f && w <= FLT_MAX)) refuse("weight not finite and >= 0");
      if (std::memcmp(&bins[x].alias_weight, &bins[bins[x].alias].weight, sizeof(float)) != 0)
        refuse("alias weight differs from the weight of its bin");
      sum += w;
    }
    row_sum[y] = sum;
    total += sum;
    if (!(sum > 0.0)) continue;  // a zero row is never drawn; its uniform coins only serve invert()
    drawn_shares(bins, W, share);
    for (std::size_t x = 0; x < W; ++x)
      if (!share_matches(share[x] / double(W), double(bins[x].weight) / sum)) refuse("coins do not match the weights");
  }
  if (!(total > 0.0)) refuse("all weights are zero");
  drawn_shares(rows_.data(), H, share);
  for (std::size_t y = 0; y < H; ++y)
    if (!share_matches(share[y] / double(H), row_sum[y] / total)) refuse("row coins do not match the row sums");
  const double expected_scale = double(W) * double(H) / total;
  if (!(std::abs(pdf_scale_ - expected_scale) <= 1e-5 * expected_scale)) refuse("pdf scale does not match the weights");
}

void AliasDistribution2D::save(BlobWriter& out) const {
  save_base(out);
  out.scalar<double>(pdf_scale_);  // first: puts the texel bins at blob offset 64, one bin per 16-byte slot of a line
  out.array(texels_);
  out.array(rows_);
}

AliasDistribution2D::AliasDistribution2D(const float* weights, int width, int height)
    : StoredDistribution2D(width, height), width_f_(width), height_f_(height) {
  sampling::require_weights(weights);
  const std::size_t W = std::size_t(width), H = std::size_t(height);
  texels_.resize(W * H);
  rows_.resize(H);
  std::vector<double> row_sum(H);

  const auto build_rows = [&](int y0, int y1) {
    std::vector<double> scaled(W);
    std::vector<std::uint32_t> work(W);
    for (int y = y0; y < y1; ++y) {
      AliasBin* bins = texels_.data() + std::size_t(y) * W;
      const float* row = weights + std::size_t(y) * W;
      double sum = 0.0;
      for (int x = 0; x < width; ++x) {
        bins[x].weight = sanitize_weight(row[x]);
        sum += bins[x].weight;
      }
      row_sum[y] = sum;
      if (sum > 0.0)
        build_vose(
            width, [bins](int x) { return double(bins[x].weight); }, sum, bins, scaled.data(), work.data());
      else
        make_uniform(width, bins);  // never drawn (zero marginal) unless the whole map is zero
      fill_alias_weights(bins, W);
    }
  };
  if (W * H >= kParallelTexels)
    tbb::parallel_for(tbb::blocked_range<int>(0, height, 16),
                      [&](const tbb::blocked_range<int>& r) { build_rows(r.begin(), r.end()); });
  else
    build_rows(0, height);

  double sum = 0.0;  // fixed order: independent of the thread count
  for (int y = 0; y < height; ++y) {
    sum += row_sum[y];
    fallback_rows_ += !(row_sum[y] > 0.0);
  }
  integral_ = sum / (double(W) * double(H));
  uniform_fallback_ = !(sum > 0.0);
  if (uniform_fallback_) {
    make_uniform(height, rows_.data());
    for (AliasBin& b : texels_) b.weight = b.alias_weight = 1.0f;
    pdf_scale_ = 1.0;
    return;
  }
  std::vector<double> scaled(H);
  std::vector<std::uint32_t> work(H);
  build_vose(
      height, [&](int y) { return row_sum[y]; }, sum, rows_.data(), scaled.data(), work.data());
  pdf_scale_ = (double(W) * double(H)) / sum;
}

DistributionSample AliasDistribution2D::sample(Vec2 u) const {
  const TexelSample t = pick(u);
  DistributionSample s;
  s.uv = Vec2((t.x + t.fx) / width_f_, (t.y + t.fy) / height_f_);
  s.pdf = t.pdf;
  s.x = t.x;
  s.y = t.y;
  return s;
}

TexelSample AliasDistribution2D::sample_texel(Vec2 u) const { return pick(u); }

void AliasDistribution2D::sample_texels(std::span<const Vec2> u, std::span<TexelSample> out) const {
  sampling::for_each_group(u.size(),
                           [&](std::size_t g, std::size_t n) { pick_group(u.data() + g, out.data() + g, n); });
}

void AliasDistribution2D::pick_group(const Vec2* u, TexelSample* out, std::size_t n) const {
  constexpr std::size_t G = sampling::kSampleGroup;
  std::uint32_t y[G], candidate[G];
  double coin_y[G], coin_x[G];
  // Row candidates; prefetch their marginal bins (8 bytes a row: usually cached, but not on tall maps).
  for (std::size_t k = 0; k < n; ++k) {
    y[k] = alias_candidate(clamp_decision(u[k].y), height_f_, coin_y[k]);
    __builtin_prefetch(rows_.data() + y[k]);
  }
  // Row coins and column candidates; prefetch each chosen row's column bin, the miss of this warp.
  for (std::size_t k = 0; k < n; ++k) {
    const RowBin& row_bin = rows_[y[k]];
    if (!alias_keep(row_bin, coin_y[k], out[k].fy)) y[k] = row_bin.alias;
    candidate[k] = alias_candidate(clamp_decision(u[k].x), width_f_, coin_x[k]);
    __builtin_prefetch(texels_.data() + std::size_t(y[k]) * std::size_t(width_) + candidate[k]);
  }
  // Column coins: the bins are in flight or arrived.
  for (std::size_t k = 0; k < n; ++k) {
    const AliasBin& bin = texels_[std::size_t(y[k]) * std::size_t(width_) + candidate[k]];
    const bool keep = alias_keep(bin, coin_x[k], out[k].fx);
    out[k].x = static_cast<int>(keep ? candidate[k] : bin.alias);
    out[k].y = static_cast<int>(y[k]);
    out[k].pdf = double(keep ? bin.weight : bin.alias_weight) * pdf_scale_;
  }
}

double AliasDistribution2D::pdf(Vec2 uv) const {
  if (!sampling::in_unit_square(uv)) return 0.0;
  const int x = sampling::texel_index(uv.x, width_);
  const int y = sampling::texel_index(uv.y, height_);
  return texels_[std::size_t(y) * std::size_t(width_) + std::size_t(x)].weight * pdf_scale_;
}

double AliasDistribution2D::texel_probability(int x, int y) const {
  if (x < 0 || x >= width_ || y < 0 || y >= height_) return 0.0;
  return alias_probability(rows_.data(), height_, y) *
         alias_probability(texels_.data() + std::size_t(y) * std::size_t(width_), width_, x);
}

std::size_t AliasDistribution2D::bytes() const { return texels_.bytes() + rows_.bytes(); }

}  // namespace envkit
