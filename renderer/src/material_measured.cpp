/// Measured isotropic BRDF from a MERL binary file: trilinear interpolation of the table, sampling by tabulated
/// inversion over half vectors, one table per theta_o bin (see material.h).
#include <envkit/render/material.h>
#include <envkit/sampling/distribution_cdf.h>
#include <tbb/parallel_for.h>

#include <array>
#include <optional>
#include <vector>

#include "material_microfacet.h"
#include "merl.h"

namespace envkit::render {

namespace {

/// The sampling tables' shape (material.h states the same numbers).
constexpr int kThetaOBins = 32;                         // uniform in theta_o over [0, pi/2)
constexpr int kHalfThetaCells = merl::kThetaHalfCells;  // rows: theta_half = (pi/2) v^2, v uniform in rows
constexpr int kHalfPhiCells = 128;                      // columns: phi_half - phi_o, uniform over [0, 2 pi)
constexpr double kHalfPhiStep = kTwoPi / kHalfPhiCells;
/// Share of each table spread uniformly over the solid angle of half vectors, so that every direction above the
/// horizon has a positive density wherever the tabulated lobe missed it.
constexpr double kDefensiveShare = 1e-3;
/// A lobe whose normal-incidence quantiles match a GGX alpha at least this is as wide as a Lambertian lobe (which
/// matches 0.51 at the median and 0.57 at the 5% quantile under the same measure): reported as 1.
constexpr double kLambertianAlpha = 0.5;

/// cos theta_half at the upper edge (toward the horizon) of half-vector row `row` (row = kHalfThetaCells: pi/2).
double row_edge_cos(int row) {
  const double v = double(row) / kHalfThetaCells;
  return std::cos(v * v * (kPi / 2.0));
}

/// The row of a half vector with cos theta_half = z.
int row_of(double z) {
  const double v = std::sqrt(std::acos(std::clamp(z, -1.0, 1.0)) / (kPi / 2.0));
  return std::clamp(int(v * kHalfThetaCells), 0, kHalfThetaCells - 1);
}

/// Solid angle of a half-vector cell of row `row`.
double cell_solid_angle(int row) { return kHalfPhiStep * (row_edge_cos(row) - row_edge_cos(row + 1)); }

/// The theta_o bin of cos theta_o = z.
int bin_of(double z) {
  const double theta = std::acos(std::clamp(z, 0.0, 1.0));
  return std::clamp(int(theta / (kPi / 2.0) * kThetaOBins), 0, kThetaOBins - 1);
}

/// Rotation about z that takes wo's azimuth to 0: the frame of the sampling tables (isotropy: only phi - phi_o
/// matters). Identity for wo at the pole.
struct AzimuthFrame {
  double c = 1.0, s = 0.0;
  explicit AzimuthFrame(const Vec3& wo) {
    const double r = std::sqrt(wo.x * wo.x + wo.y * wo.y);
    if (r > 0.0) c = wo.x / r, s = wo.y / r;
  }
  Vec3 to_table(const Vec3& v) const { return Vec3(c * v.x + s * v.y, -s * v.x + c * v.y, v.z); }
  Vec3 to_local(const Vec3& v) const { return Vec3(c * v.x - s * v.y, s * v.x + c * v.y, v.z); }
};

/// Linear interpolation weights between cell centres along one axis of n cells; x is the continuous cell
/// coordinate (centre of cell i at i). Clamped at the ends, or periodic.
struct Axis {
  int i0 = 0, i1 = 0;
  double t = 0.0;
  static Axis clamped(double x, int n) {
    x = std::clamp(x, 0.0, double(n - 1));
    Axis a;
    a.i0 = std::min(int(x), n - 1);
    a.i1 = std::min(a.i0 + 1, n - 1);
    a.t = x - a.i0;
    return a;
  }
  static Axis periodic(double x, int n) {
    const double f = std::floor(x);
    Axis a;
    a.t = std::clamp(x - f, 0.0, 1.0);
    a.i0 = ((int(f) % n) + n) % n;
    a.i1 = (a.i0 + 1) % n;
    return a;
  }
};

class MeasuredMaterial final : public Material {
 public:
  explicit MeasuredMaterial(merl::Data data) : rgb_(std::move(data.rgb)) {
    build_tables();
    fit_lobe_alphas();
  }

  const char* name() const override { return "measured"; }
  double widest_lobe_alpha() const override { return widest_alpha_; }
  double narrowest_lobe_alpha() const override { return narrowest_alpha_; }
  double narrowest_lobe_probability(const Vec3& wo) const override {
    if (!detail::above(wo)) return 0.0;
    return narrowest_alpha_ < widest_alpha_ ? 0.5 : 1.0;
  }

  Vec3 eval(const Vec3& wo, const Vec3& wi) const override {
    merl::HalfDiff hd;
    if (!detail::above(wo) || !detail::above(wi) || !merl::half_diff(wo, wi, hd)) return Vec3(0.0);
    const Vec3 f = lookup(hd) * wi.z;
    return std::isfinite(f.x + f.y + f.z) ? f : Vec3(0.0);
  }

  double pdf(const Vec3& wo, const Vec3& wi) const override {
    Vec3 h;
    if (!detail::above(wo) || !detail::above(wi) || !detail::half_vector(wo, wi, h)) return 0.0;
    return half_vector_pdf(wo, h);
  }

  bool sample(const Vec3& wo, Vec2 u2, double /*u_lobe*/, BsdfSample& out) const override {
    if (!detail::above(wo)) return false;
    const CdfDistribution2D& table = *tables_[std::size_t(bin_of(wo.z))];
    const TexelSample cell = table.pick(u2);
    // Uniform in solid angle inside the cell: cos theta_half linear between the row's edges, phi linear.
    const double z0 = row_edge_cos(cell.y), z1 = row_edge_cos(cell.y + 1);
    const double z = z0 - cell.fy * (z0 - z1), r = safe_sqrt(1.0 - z * z);
    const double phi = (cell.x + cell.fx) * kHalfPhiStep;
    const Vec3 h = AzimuthFrame(wo).to_local(Vec3(r * std::cos(phi), r * std::sin(phi), z));
    if (!((wo ^ h) > 0.0)) return false;
    return detail::reflection_sample(*this, wo, h, out);
  }

 private:
  /// f (RGB, 1/sr) at Rusinkiewicz coordinates: trilinear between cell centres, clamped in theta_half and
  /// theta_diff, periodic (period pi) in phi_diff.
  Vec3 lookup(const merl::HalfDiff& hd) const {
    const Axis a =
        Axis::clamped(std::sqrt(hd.theta_half / (kPi / 2.0)) * merl::kThetaHalfCells - 0.5, merl::kThetaHalfCells);
    const Axis b = Axis::clamped(hd.theta_diff / (kPi / 2.0) * merl::kThetaDiffCells - 0.5, merl::kThetaDiffCells);
    const Axis c = Axis::periodic(hd.phi_diff / kPi * merl::kPhiDiffCells - 0.5, merl::kPhiDiffCells);
    double sum[3] = {0.0, 0.0, 0.0};
    for (int i = 0; i < 8; ++i) {
      const double w = ((i & 1) ? a.t : 1.0 - a.t) * ((i & 2) ? b.t : 1.0 - b.t) * ((i & 4) ? c.t : 1.0 - c.t);
      const float* v = &rgb_[3 * merl::cell_index((i & 1) ? a.i1 : a.i0, (i & 2) ? b.i1 : b.i0, (i & 4) ? c.i1 : c.i0)];
      for (int k = 0; k < 3; ++k) sum[k] += w * double(v[k]);
    }
    return Vec3(sum[0], sum[1], sum[2]);
  }

  /// Solid-angle density of wi = reflect(wo, h) for a unit half vector h (local frame): the probability of h's
  /// cell over the cell's solid angle, times the Jacobian d omega_h / d omega_i = 1 / (4 wo.h).
  double half_vector_pdf(const Vec3& wo, const Vec3& h) const {
    const double cos_oh = wo ^ h;
    if (!(cos_oh > 0.0) || !(h.z > 0.0)) return 0.0;
    const Vec3 h_table = AzimuthFrame(wo).to_table(h);
    double phi = std::atan2(h_table.y, h_table.x);
    if (phi < 0.0) phi += kTwoPi;
    const int x = std::clamp(int(phi / kHalfPhiStep), 0, kHalfPhiCells - 1);
    const int y = row_of(h_table.z);
    const double p = tables_[std::size_t(bin_of(wo.z))]->texel_probability(x, y) / cell_solid_angle(y);
    const double pdf = p / (4.0 * cos_oh);
    return std::isfinite(pdf) ? pdf : 0.0;
  }

  /// For each theta_o bin (wo at the bin's centre, azimuth 0): the mass of f cos over each half-vector cell,
  /// d omega_i = 4 (wo.h) d omega_h, by a 2x2 midpoint rule in (cos theta_half, phi), plus the defensive share.
  void build_tables() {
    std::vector<std::vector<float>> weights(kThetaOBins);
    tbb::parallel_for(0, kThetaOBins, [&](int bin) {
      const double theta_o = (bin + 0.5) / kThetaOBins * (kPi / 2.0);
      const Vec3 wo(std::sin(theta_o), 0.0, std::cos(theta_o));
      std::vector<double> mass(std::size_t(kHalfThetaCells) * kHalfPhiCells, 0.0);
      double total = 0.0;
      for (int y = 0; y < kHalfThetaCells; ++y) {
        const double z0 = row_edge_cos(y), z1 = row_edge_cos(y + 1);
        for (int x = 0; x < kHalfPhiCells; ++x) {
          double sum = 0.0;
          for (int s = 0; s < 4; ++s) {
            const double z = z0 - (0.25 + 0.5 * (s & 1)) * (z0 - z1), r = safe_sqrt(1.0 - z * z);
            const double phi = (x + 0.25 + 0.5 * (s >> 1)) * kHalfPhiStep;
            const Vec3 h(r * std::cos(phi), r * std::sin(phi), z);
            const double cos_oh = wo ^ h;
            if (!(cos_oh > 0.0)) continue;
            const Vec3 f = eval(wo, detail::reflect(wo, h).normalized());
            sum += (f.x + f.y + f.z) / 3.0 * 4.0 * cos_oh;
          }
          const double m = sum / 4.0 * cell_solid_angle(y);
          mass[std::size_t(y) * kHalfPhiCells + std::size_t(x)] = m;
          total += m;
        }
      }
      // Defensive share: uniform over the hemisphere of half vectors (2 pi sr), so proportional to each cell's
      // solid angle. With no mass at all (a black bin) the table is that uniform density alone.
      const double floor_per_sr = (total > 0.0 ? kDefensiveShare * total : 1.0) / kTwoPi;
      std::vector<float>& w = weights[std::size_t(bin)];
      w.resize(mass.size());
      for (int y = 0; y < kHalfThetaCells; ++y)
        for (int x = 0; x < kHalfPhiCells; ++x) {
          const std::size_t i = std::size_t(y) * kHalfPhiCells + std::size_t(x);
          w[i] = float(mass[i] + floor_per_sr * cell_solid_angle(y));
        }
    });
    for (const std::vector<float>& w : weights)
      tables_.push_back(std::make_unique<CdfDistribution2D>(w.data(), kHalfPhiCells, kHalfThetaCells));
  }

  /// The GGX alphas of the lobe at normal incidence (wo = z): the distribution over theta_half in [0, pi/4) of
  /// f cos_i 4 cos theta_half sin theta_half (the mass of f cos per theta_half; for a GGX lobe without masking it
  /// is D cos theta_half, whose share below t is tan^2 t / (alpha^2 + tan^2 t) before the horizon's cut). Its q
  /// quantile t_q matches the GGX alpha = tan t_q sqrt((1 - q) / (q - tan^2 t_q)) (the quantile of the cut GGX
  /// lobe solved for alpha). Narrowest: q = 0.05; widest: q = 0.5 (the median), and never below the narrowest.
  /// Alphas at or above kLambertianAlpha (and quantiles past the GGX range) are reported as 1.
  void fit_lobe_alphas() {
    constexpr int n = 4096;
    std::vector<double> cdf(n + 1, 0.0);
    const Vec3 wo(0.0, 0.0, 1.0);
    for (int i = 0; i < n; ++i) {
      const double t = (i + 0.5) / n * (kPi / 4.0);
      const Vec3 f = eval(wo, Vec3(std::sin(2.0 * t), 0.0, std::cos(2.0 * t)));
      cdf[std::size_t(i) + 1] = cdf[std::size_t(i)] + (f.x + f.y + f.z) / 3.0 * 4.0 * std::cos(t) * std::sin(t);
    }
    const auto alpha_at = [&](double q) {
      if (!(cdf[n] > 0.0)) return 1.0;
      const auto it = std::lower_bound(cdf.begin(), cdf.end(), q * cdf[n]);
      const double t = double(it - cdf.begin()) / n * (kPi / 4.0);
      const double t2 = std::tan(t) * std::tan(t);
      if (!(t2 < q)) return 1.0;
      const double alpha = std::tan(t) * std::sqrt((1.0 - q) / (q - t2));
      return alpha >= kLambertianAlpha || !std::isfinite(alpha) ? 1.0 : std::max(alpha, detail::kMinAlpha);
    };
    narrowest_alpha_ = alpha_at(0.05);
    widest_alpha_ = std::max(narrowest_alpha_, alpha_at(0.5));
  }

  std::vector<float> rgb_;                                  // f per MERL cell, interleaved RGB (merl::Data)
  std::vector<std::unique_ptr<CdfDistribution2D>> tables_;  // one per theta_o bin
  double widest_alpha_ = 1.0, narrowest_alpha_ = 1.0;
};

}  // namespace

std::unique_ptr<Material> make_measured(const std::string& merl_file, const Vec3& scale) {
  return std::make_unique<MeasuredMaterial>(merl::read(merl_file, scale));
}

}  // namespace envkit::render
