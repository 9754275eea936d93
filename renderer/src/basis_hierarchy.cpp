#include <envkit/core/error.h>
#include <envkit/core/sh_basis.h>
#include <envkit/render/basis_hierarchy.h>
#include <envkit/render/product_wavelet.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace envkit::render {

namespace {

/// Stratified points per side of each of the fit's two techniques (material sampling, uniform hemisphere).
constexpr int kFitPointsPerSide = 32;

/// Cell index of a square position, clamped to the grid (NaN -> 0).
int cell_of(double t, int n) { return t > 0.0 ? std::min(int(t * n), n - 1) : 0; }

bool power_of_two(int n) { return n > 0 && (n & (n - 1)) == 0; }

/// Legendre polynomials P_0 .. P_order at x into p.
void legendre(int order, double x, double* p) {
  p[0] = 1.0;
  if (order >= 1) p[1] = x;
  for (int l = 2; l <= order; ++l) p[l] = ((2 * l - 1) * x * p[l - 1] - (l - 1) * p[l - 2]) / l;
}

double mean(const Vec3& v) { return (v.x + v.y + v.z) / 3.0; }

}  // namespace

std::vector<EnvNode> environment_nodes(const SphericalDistribution& env, int columns, const char* who) {
  if (env.distribution().builtin() != BuiltinDistribution::Hierarchical)
    throw Error(std::string(who) + ": needs the hierarchical table (--light-method hierarchical)");
  const auto* pyramid = static_cast<const HierarchicalDistribution2D*>(&env.distribution());
  int level = 0;
  double best = 1e300;
  for (int k = 0; k <= pyramid->levels(); ++k) {
    const double d = std::abs(std::log2(double(pyramid->level_width(k))) - std::log2(double(columns)));
    if (d < best) {
      best = d;
      level = k;
    }
  }
  const auto centre = [&](int i, int n) {
    const double first = double(i << level), last = double(std::min((i + 1) << level, n));
    return 0.5 * (first + last);
  };
  std::vector<EnvNode> nodes;
  for (int j = 0; j < pyramid->level_height(level); ++j)
    for (int i = 0; i < pyramid->level_width(level); ++i) {
      const double e = pyramid->node(level, i, j);
      if (!(e > 0.0)) continue;
      const double px = centre(i, env.width()), py = centre(j, env.height());
      const int x = std::min(int(px), env.width() - 1), y = std::min(int(py), env.height() - 1);
      nodes.push_back({env.direction_in_texel(x, y, std::min(px - x, 0.5), std::min(py - y, 0.5)), e});
    }
  return nodes;
}

// ---------------------------------------------------------------------------------------------------------------
// BasisHierarchy

BasisHierarchy::BasisHierarchy(int resolution, int count, const std::vector<double>& finest)
    : resolution_(resolution), count_(count) {
  if (!power_of_two(resolution) || resolution < 2 || resolution > 1024)
    throw Error("basis hierarchy resolution " + std::to_string(resolution) + ": must be a power of two in 2..1024");
  const std::size_t K = std::size_t(count);
  if (count < 1 || finest.size() != std::size_t(resolution) * std::size_t(resolution) * K)
    throw Error("basis hierarchy: the finest level needs R x R x K integrals");
  while ((1 << levels_) < resolution) ++levels_;
  level_offset_.resize(std::size_t(levels_) + 1);
  std::size_t nodes = 0;
  for (int k = 0; k <= levels_; ++k) {
    level_offset_[std::size_t(k)] = nodes;
    nodes += (std::size_t(1) << k) * (std::size_t(1) << k);
  }
  nodes_.resize(nodes * K);
  // Sums in double from the finest level up; each level stored once as float.
  std::vector<double> level(finest);
  for (int k = levels_;; --k) {
    const std::size_t n = std::size_t(1) << k;
    std::copy(level.begin(), level.end(), nodes_.begin() + std::ptrdiff_t(level_offset_[std::size_t(k)] * K));
    if (k == 0) break;
    std::vector<double> up((n / 2) * (n / 2) * K, 0.0);
    for (std::size_t y = 0; y < n; ++y)
      for (std::size_t x = 0; x < n; ++x)
        for (std::size_t i = 0; i < K; ++i) up[((y / 2) * (n / 2) + x / 2) * K + i] += level[(y * n + x) * K + i];
    level.swap(up);
  }
}

const float* BasisHierarchy::node(int level, int x, int y) const {
  const std::size_t n = std::size_t(1) << level;
  return nodes_.data() +
         (level_offset_[std::size_t(level)] + std::size_t(y) * n + std::size_t(x)) * std::size_t(count_);
}

namespace {

/// Four partial sums: the additions of one sum would wait on each other.
double dot(const double* c, const float* v, int K) {
  double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
  int i = 0;
  for (; i + 4 <= K; i += 4) {
    s0 += c[i] * double(v[i]);
    s1 += c[i + 1] * double(v[i + 1]);
    s2 += c[i + 2] * double(v[i + 2]);
    s3 += c[i + 3] * double(v[i + 3]);
  }
  for (; i < K; ++i) s0 += c[i] * double(v[i]);
  return (s0 + s1) + (s2 + s3);
}

}  // namespace

double BasisHierarchy::total(const double* c) const { return dot(c, node(0, 0, 0), count_); }

void BasisHierarchy::children(const double* c, int level, int x, int y, double* mass) const {
  double sum = 0.0;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) {
      const double m = dot(c, node(level, 2 * x + i, 2 * y + j), count_);
      mass[j * 2 + i] = m > 0.0 && std::isfinite(m) ? m : 0.0;
      sum += mass[j * 2 + i];
    }
  if (!(sum > 0.0) || !std::isfinite(sum)) std::fill(mass, mass + 4, 1.0);
}

bool BasisHierarchy::can_sample(const double* c) const {
  double sum = 0.0;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) {
      const double m = dot(c, node(1, i, j), count_);
      if (m > 0.0 && std::isfinite(m)) sum += m;
    }
  return sum > 0.0 && std::isfinite(sum);
}

DirectionSample BasisHierarchy::sample(const double* c, Vec2 u) const {
  int x = 0, y = 0;
  double probability = 1.0;
  for (int k = 1; k <= levels_; ++k) {
    double m[4];
    children(c, k, x, y, m);
    const double left = m[0] + m[2], right = m[1] + m[3], sum = left + right;
    // Column first, then the child in the column; each coordinate is rescaled to [0, 1) for the next level.
    const double p_left = left / sum;
    int i = 0;
    if (u.x < p_left) {
      u.x = p_left > 0.0 ? u.x / p_left : 0.0;
    } else {
      i = 1;
      u.x = p_left < 1.0 ? (u.x - p_left) / (1.0 - p_left) : 0.0;
    }
    const double column = i == 0 ? left : right;
    const double p_low = m[i] / column;
    int j = 0;
    if (u.y < p_low) {
      u.y = p_low > 0.0 ? u.y / p_low : 0.0;
    } else {
      j = 1;
      u.y = p_low < 1.0 ? (u.y - p_low) / (1.0 - p_low) : 0.0;
    }
    u.x = std::clamp(u.x, 0.0, std::nextafter(1.0, 0.0));
    u.y = std::clamp(u.y, 0.0, std::nextafter(1.0, 0.0));
    probability *= m[j * 2 + i] / sum;
    x = 2 * x + i;
    y = 2 * y + j;
  }
  const double R = double(resolution_);
  DirectionSample s;
  s.direction = cap_from_square(Vec2((x + u.x) / R, (y + u.y) / R), kWholeSphere);
  s.pdf = probability * R * R / kFourPi;
  s.x = x;
  s.y = y;
  return s;
}

double BasisHierarchy::pdf(const double* c, const Vec3& direction) const {
  const double len = direction.length();
  if (!(len > 0.0) || !std::isfinite(len)) return 0.0;
  const Vec2 uv = square_from_cap(direction, kWholeSphere);
  const int cx = cell_of(uv.x, resolution_), cy = cell_of(uv.y, resolution_);
  double probability = 1.0;
  for (int k = 1; k <= levels_; ++k) {
    const int shift = levels_ - k;
    const int x = cx >> shift, y = cy >> shift;
    double m[4];
    children(c, k, x >> 1, y >> 1, m);
    probability *= m[(y & 1) * 2 + (x & 1)] / (m[0] + m[1] + m[2] + m[3]);
  }
  return probability * double(resolution_) * double(resolution_) / kFourPi;
}

// ---------------------------------------------------------------------------------------------------------------
// Options

namespace {

std::string number_text(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

}  // namespace

std::optional<BasisOptionProblem> out_of_range(const BasisProductOptions& o) {
  using M = BasisOptionProblem::Member;
  if (o.order < 1 || o.order > 16) return BasisOptionProblem{M::Order, std::to_string(o.order), "must be in 1..16"};
  if (!power_of_two(o.resolution) || o.resolution < 2 || o.resolution > 512)
    return BasisOptionProblem{M::Resolution, std::to_string(o.resolution), "must be a power of two in 2..512"};
  if (o.wo_bins < 2 || o.wo_bins > 256)
    return BasisOptionProblem{M::WoBins, std::to_string(o.wo_bins), "must be in 2..256"};
  if (!(o.defensive > 0.0 && o.defensive <= 1.0))
    return BasisOptionProblem{M::Defensive, number_text(o.defensive), "must be in (0, 1]"};
  return std::nullopt;
}

void check_options(const BasisProductOptions& o, const char* who) {
  static constexpr const char* kNames[] = {"order", "resolution", "wo bins", "defensive share"};
  if (const std::optional<BasisOptionProblem> bad = out_of_range(o))
    throw Error(std::string(who) + " " + kNames[int(bad->member)] + " " + bad->value + ": " + bad->rule);
}

// ---------------------------------------------------------------------------------------------------------------
// BsdfLobeFit

namespace {

/// The fit of g = BSDF x cos for one outgoing elevation: a_0..a_order, then b_0..b_order.
std::vector<double> fit_lobes(const Material& material, double theta_o, int order) {
  const Vec3 wo(std::sin(theta_o), 0.0, std::cos(theta_o));
  const Vec3 n(0.0, 0.0, 1.0), r(-wo.x, 0.0, wo.z);
  const int S = kFitPointsPerSide, N = S * S;
  std::vector<double> pn(std::size_t(order) + 1, 0.0), pr(pn.size(), 0.0), leg_n(pn.size()), leg_r(pn.size());
  const double p_uniform = 1.0 / kTwoPi;
  const auto add = [&](const Vec3& wi) {
    if (!(wi.z > 0.0)) return;
    const double g = mean(material.eval(wo, wi));
    const double p = material.pdf(wo, wi) + p_uniform;  // balance heuristic over the two techniques' N points each
    if (!(g > 0.0) || !std::isfinite(g) || !std::isfinite(p)) return;
    const double w = g / (double(N) * p);
    legendre(order, n ^ wi, leg_n.data());
    legendre(order, r ^ wi, leg_r.data());
    for (int l = 0; l <= order; ++l) {
      pn[std::size_t(l)] += w * leg_n[std::size_t(l)];
      pr[std::size_t(l)] += w * leg_r[std::size_t(l)];
    }
  };
  for (int k = 0; k < N; ++k) {
    const Vec2 u((k % S + 0.5) / S, (k / S + 0.5) / S);
    add(cap_from_square(u, 1.0));  // uniform over the hemisphere
    BsdfSample bs;
    const double u_lobe = std::fmod((k + 0.5) * 0.6180339887498949, 1.0);
    if (material.sample(wo, u, u_lobe, bs) && !bs.is_delta && bs.pdf > 0.0) add(bs.wi);
  }
  std::vector<double> fit(2 * pn.size(), 0.0);
  std::vector<double> leg_c(pn.size());
  legendre(order, n ^ r, leg_c.data());
  for (int l = 0; l <= order; ++l) {
    const double scale = (2.0 * l + 1.0) / kFourPi;
    const double x = pn[std::size_t(l)] * scale, y = pr[std::size_t(l)] * scale, c = leg_c[std::size_t(l)];
    const double d = 1.0 + kLobeFitRidge, det = d * d - c * c;
    fit[std::size_t(l)] = (d * x - c * y) / det;
    fit[pn.size() + std::size_t(l)] = (d * y - c * x) / det;
  }
  return fit;
}

}  // namespace

BsdfLobeFit::BsdfLobeFit(const std::vector<const Material*>& materials, int order, int wo_bins)
    : order_(order), wo_bins_(wo_bins) {
  for (const Material* m : materials)
    if (m && !m->is_pure_delta() && std::find(materials_.begin(), materials_.end(), m) == materials_.end())
      materials_.push_back(m);
  const std::size_t per_bin = 2 * (std::size_t(order) + 1), bins = std::size_t(wo_bins);
  fits_.assign(materials_.size(), std::vector<double>(bins * per_bin));
  tbb::parallel_for(std::size_t(0), materials_.size() * bins, [&](std::size_t t) {
    const std::size_t mi = t / bins, bin = t % bins;
    const double theta_o = (double(bin) + 0.5) / double(bins) * (kPi / 2.0);
    const std::vector<double> fit = fit_lobes(*materials_[mi], theta_o, order_);
    std::copy(fit.begin(), fit.end(), fits_[mi].begin() + std::ptrdiff_t(bin * per_bin));
  });
}

bool BsdfLobeFit::lobes(const Material& material, double cos_theta_o, std::vector<double>& a,
                        std::vector<double>& b) const {
  const auto it = std::find(materials_.begin(), materials_.end(), &material);
  if (it == materials_.end()) return false;
  const std::vector<double>& fit = fits_[std::size_t(it - materials_.begin())];
  const std::size_t L = std::size_t(order_) + 1, per_bin = 2 * L;
  // Linear in theta_o between bin centres, constant beyond the first and last.
  const double theta = std::acos(std::clamp(cos_theta_o, 0.0, 1.0));
  const double t = std::clamp(theta / (kPi / 2.0) * wo_bins_ - 0.5, 0.0, double(wo_bins_ - 1));
  const std::size_t b0 = std::size_t(t), b1 = std::min(b0 + 1, std::size_t(wo_bins_ - 1));
  const double f = t - double(b0);
  a.resize(L);
  b.resize(L);
  for (std::size_t l = 0; l < L; ++l) {
    a[l] = (1.0 - f) * fit[b0 * per_bin + l] + f * fit[b1 * per_bin + l];
    b[l] = (1.0 - f) * fit[b0 * per_bin + L + l] + f * fit[b1 * per_bin + L + l];
  }
  return true;
}

void BsdfLobeFit::coefficients(const Material& material, const Vec3& normal, const Vec3& wo, double* out) const {
  const int K = sh_count(order_);
  std::fill(out, out + K, 0.0);
  const double cos_o = normal ^ wo;
  std::vector<double> a, b;
  if (!lobes(material, cos_o, a, b)) {
    out[0] = std::sqrt(kFourPi);  // the constant 1 = sqrt(4 pi) Y_00
    return;
  }
  // a_l P_l(a . w) is the zonal function of band coefficient z_l = sqrt(4 pi / (2l + 1)) a_l around a.
  for (int l = 0; l <= order_; ++l) {
    const double z = std::sqrt(kFourPi / (2.0 * l + 1.0));
    a[std::size_t(l)] *= z;
    b[std::size_t(l)] *= z;
  }
  const Vec3 r = normal * (2.0 * cos_o) - wo;
  std::vector<double> turned(static_cast<std::size_t>(K));
  sh_rotate_zonal(order_, a.data(), normal, out);
  sh_rotate_zonal(order_, b.data(), r / r.length(), turned.data());
  for (int i = 0; i < K; ++i) out[i] += turned[std::size_t(i)];
}

std::size_t BsdfLobeFit::bytes() const {
  std::size_t b = 0;
  for (const auto& f : fits_) b += f.size() * sizeof(double);
  return b;
}

// ---------------------------------------------------------------------------------------------------------------
// BasisProductPoint

BasisProductPoint::BasisProductPoint(const BasisHierarchy& hierarchy, std::vector<double> coefficients,
                                     const SphericalDistribution& env, double defensive)
    : hierarchy_(&hierarchy), coefficients_(std::move(coefficients)), env_(&env), defensive_(defensive) {
  if (!hierarchy_->can_sample(coefficients_.data())) defensive_ = 1.0;
}

DirectionSample BasisProductPoint::sample(Vec2 u) const {
  const double d = defensive_;
  if (u.x < d) {
    DirectionSample s = env_->sample(Vec2(std::min(u.x / d, std::nextafter(1.0, 0.0)), u.y));
    s.pdf = pdf(s.direction);
    return s;
  }
  // The warping's own density is the one its descent multiplied: only the table's is looked up.
  DirectionSample s =
      hierarchy_->sample(coefficients_.data(), Vec2(std::min((u.x - d) / (1.0 - d), std::nextafter(1.0, 0.0)), u.y));
  const double p = d * env_->pdf(s.direction) + (1.0 - d) * s.pdf;
  s.pdf = std::isfinite(p) ? p : 0.0;
  return s;
}

double BasisProductPoint::pdf(const Vec3& direction) const {
  const double p_env = env_->pdf(direction);
  if (defensive_ >= 1.0) return p_env;
  const double p = defensive_ * p_env + (1.0 - defensive_) * hierarchy_->pdf(coefficients_.data(), direction);
  return std::isfinite(p) ? p : 0.0;
}

}  // namespace envkit::render
