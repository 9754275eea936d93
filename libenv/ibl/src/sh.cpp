#include <envkit/core/error.h>
#include <envkit/ibl/sh.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/resample/filter.h>
#include <tbb/parallel_for.h>

#include <array>
#include <cmath>
#include <nlohmann/json.hpp>

namespace envkit {

std::string sh_window_name(ShWindow window) {
  switch (window) {
    case ShWindow::None:
      return "none";
    case ShWindow::Hanning:
      return "hanning";
    case ShWindow::Lanczos:
      return "lanczos";
  }
  return "none";
}

ShWindow parse_sh_window(const std::string& name) {
  if (name == "none") return ShWindow::None;
  if (name == "hanning" || name == "hann") return ShWindow::Hanning;
  if (name == "lanczos") return ShWindow::Lanczos;
  throw Error("unknown SH window '" + name + "' (expected none, hanning or lanczos)");
}

double sh_cosine_lobe(int l) {
  switch (l) {
    case 0:
      return kPi;
    case 1:
      return 2.0 * kPi / 3.0;
    case 2:
      return kPi / 4.0;
  }
  if (l < 0 || l % 2 == 1) return 0.0;
  // Even l (Ramamoorthi and Hanrahan 2001, eq. 8): 2 pi (-1)^(l/2 - 1) / ((l + 2)(l - 1)) l! / (2^l ((l/2)!)^2),
  // the last factor C(l, l/2) / 2^l built as a product so that no factorial overflows.
  double binomial = 1.0;
  for (int k = 1; k <= l / 2; ++k) binomial *= double(l / 2 + k) / (4.0 * k);
  const double sign = (l / 2) % 2 == 1 ? 1.0 : -1.0;
  return 2.0 * kPi * sign / ((l + 2.0) * (l - 1.0)) * binomial;
}

double sh_window_factor(ShWindow window, int l, int order) {
  const double t = kPi * l / (order + 1.0);
  switch (window) {
    case ShWindow::None:
      return 1.0;
    case ShWindow::Hanning:
      return 0.5 * (1.0 + std::cos(t));
    case ShWindow::Lanczos:
      return l == 0 ? 1.0 : std::sin(t) / t;
  }
  return 1.0;
}

std::vector<std::vector<double>> ShCoefficients::irradiance() const {
  std::vector<std::vector<double>> out = radiance;
  for (auto& ch : out)
    for (int l = 0; l <= order; ++l)
      for (int m = -l; m <= l; ++m) ch[l * (l + 1) + m] *= sh_cosine_lobe(l) * sh_window_factor(window, l, order);
  return out;
}

std::vector<std::vector<double>> ShCoefficients::irradiance_over_pi() const {
  std::vector<std::vector<double>> out = irradiance();
  for (auto& ch : out)
    for (double& v : ch) v /= kPi;
  return out;
}

double ShCoefficients::eval_irradiance(int channel, const Vec3& n) const {
  std::vector<double> y(sh_count(order));
  sh_basis(order, n, y.data());
  double e = 0.0;
  for (int l = 0; l <= order; ++l)
    for (int m = -l; m <= l; ++m) {
      const int i = l * (l + 1) + m;
      e += sh_cosine_lobe(l) * sh_window_factor(window, l, order) * radiance[channel][i] * y[i];
    }
  return e / kPi;
}

double ShCoefficients::eval_radiance(int channel, const Vec3& n) const {
  std::vector<double> y(sh_count(order));
  sh_basis(order, n, y.data());
  double l = 0.0;
  for (int i = 0; i < sh_count(order); ++i) l += radiance[channel][i] * y[i];
  return l;
}

nlohmann::json ShCoefficients::to_json() const {
  nlohmann::json j;
  j["order"] = order;
  j["coefficients_per_channel"] = sh_count(order);
  j["basis"] =
      "real spherical harmonics, orthonormal on the sphere, no "
      "Condon-Shortley phase, index l*(l+1)+m, in the world "
      "direction (x, y, z); envkit/GL world: +Y up";
  if (order > 3) {
    j["basis_functions"] =
        "Y_lm = sqrt(2) K_lm P_lm(z) (cos m phi for m > 0, sin |m| phi for m < 0), Y_l0 = K_l0 P_l0(z), "
        "K_lm = sqrt((2l+1)/(4 pi) (l-m)!/(l+m)!), P_lm without the (-1)^m phase, phi from +x to +y";
  } else
    j["basis_functions"] = {"0.282095",
                            "0.488603 y",
                            "0.488603 z",
                            "0.488603 x",
                            "1.092548 xy",
                            "1.092548 yz",
                            "0.315392 (3z^2-1)",
                            "1.092548 xz",
                            "0.546274 (x^2-y^2)",
                            "0.590044 y(3x^2-y^2)",
                            "2.890611 xyz",
                            "0.457046 y(4z^2-x^2-y^2)",
                            "0.373176 z(2z^2-3x^2-3y^2)",
                            "0.457046 x(4z^2-x^2-y^2)",
                            "1.445306 z(x^2-y^2)",
                            "0.590044 x(x^2-3y^2)"};
  j["window"] = sh_window_name(window);
  j["window_factors"] = nlohmann::json::array();
  for (int l = 0; l <= order; ++l) j["window_factors"].push_back(sh_window_factor(window, l, order));
  j["cosine_lobe_A_l"] = nlohmann::json::array();
  for (int l = 0; l <= order; ++l) j["cosine_lobe_A_l"].push_back(sh_cosine_lobe(l));
  j["channels"] = channel_names;
  const auto irr = irradiance();
  const auto irr_pi = irradiance_over_pi();
  nlohmann::json rad = nlohmann::json::object(), e = nlohmann::json::object(), e_pi = nlohmann::json::object();
  for (std::size_t c = 0; c < channel_names.size(); ++c) {
    rad[channel_names[c]] = radiance[c];
    e[channel_names[c]] = irr[c];
    e_pi[channel_names[c]] = irr_pi[c];
  }
  j["radiance"] = {{"definition", "L_lm = integral of L(w) Y_lm(w) dw (unwindowed)"}, {"coefficients", rad}};
  j["irradiance"] = {{"definition", "E(n) = sum_lm c_lm Y_lm(n), c_lm = A_l window_l L_lm"}, {"coefficients", e}};
  j["irradiance_over_pi"] = {{"definition",
                              "E(n)/pi = sum_lm c_lm Y_lm(n), c_lm = A_l window_l L_lm "
                              "/ pi (Lambertian BRDF 1/pi folded in)"},
                             {"coefficients", e_pi}};
  return j;
}

namespace {

/// The sums L x solid angle x Y_i of one row of a map, per colour channel k, into acc[k (kOrder + 1)^2 + i].
struct RowProjection {
  const MapRef& src;
  const TexelDirections& dirs;
  const SolidAngleTable& omega;
  const TexelSource& coverage;
  const std::vector<int>& colour;

  /// Adds row y with the closed-form basis of band count kOrder + 1 (a constant: the values stay in registers).
  template <int kOrder>
  void add(int y, double* acc) const {
    constexpr int kCount = sh_count(kOrder);
    double b[kCount];
    add_row(y, acc, kCount, b, [&](const Vec3& d) { sh_basis_closed_form<kOrder>(d, b); });
  }

  /// Adds row y with the basis of any order.
  void add_any(int order, int y, double* acc) const {
    std::vector<double> b(sh_count(order));
    add_row(y, acc, int(b.size()), b.data(), [&](const Vec3& d) { sh_basis(order, d, b.data()); });
  }

  template <class Basis>
  [[gnu::always_inline]] void add_row(int y, double* acc, int count, const double* b, Basis&& basis) const {
    const Image& img = src.image;
    for (int x = 0; x < img.width; ++x) {
      Vec3 d;
      if (!coverage.covered(std::size_t(y) * img.width + x) || !dirs.centre(x, y, d)) continue;
      // Texel directions are unit and to_world is a rotation: no normalisation (its square root and divisions
      // were most of this loop's time).
      basis(apply(src.to_world, d));
      const double o = omega(x, y);
      const float* px = img.at(x, y);
      for (std::size_t k = 0; k < colour.size(); ++k) {
        const double v = double(px[colour[k]]) * o;
        for (int i = 0; i < count; ++i) acc[k * count + i] += v * b[i];
      }
    }
  }
};

}  // namespace

ShCoefficients project_sh(const MapRef& src, int order, ShWindow window) {
  if (order < 1 || order > kMaxShOrder)
    throw Error("SH order must be 1 to " + std::to_string(kMaxShOrder) + ", not " + std::to_string(order));
  const Image& img = src.image;
  const int count = sh_count(order);
  std::vector<int> colour;
  ShCoefficients sh;
  sh.order = order;
  sh.window = window;
  for (int c = 0; c < img.channels; ++c)
    if (c != img.alpha_channel) {
      colour.push_back(c);
      sh.channel_names.push_back(c < int(img.channel_names.size()) ? img.channel_names[c]
                                                                   : std::string("C").append(std::to_string(c)));
    }
  const TexelDirections dirs(src.param);
  const SolidAngleTable omega(src.param);
  const TexelSource coverage(img, src.param);
  // One partial sum per row (fixed), added in row order: independent of the
  // thread count.
  std::vector<std::vector<double>> rows(img.height, std::vector<double>(colour.size() * count, 0.0));
  const RowProjection projection{src, dirs, omega, coverage, colour};
  tbb::parallel_for(0, img.height, [&](int y) {
    switch (order) {
      case 1:
        return projection.add<1>(y, rows[y].data());
      case 2:
        return projection.add<2>(y, rows[y].data());
      case 3:
        return projection.add<3>(y, rows[y].data());
      default:
        return projection.add_any(order, y, rows[y].data());
    }
  });
  sh.radiance.assign(colour.size(), std::vector<double>(count, 0.0));
  for (const auto& row : rows)
    for (std::size_t k = 0; k < colour.size(); ++k)
      for (int i = 0; i < count; ++i) sh.radiance[k][i] += row[k * count + i];
  return sh;
}

}  // namespace envkit
