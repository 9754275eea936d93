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

namespace {

/// The real SH basis up to band kOrder at the unit direction d, into out[(kOrder + 1)^2]. A template, inline in the
/// projection's loop: the band count is then a constant and the values stay in registers.
template <int kOrder>
[[gnu::always_inline]] inline void basis(const Vec3& d, double* out) {
  const double x = d.x, y = d.y, z = d.z;
  out[0] = 0.28209479177387814;  // 1 / (2 sqrt(pi))
  if constexpr (kOrder >= 1) {
    const double c1 = 0.4886025119029199;  // sqrt(3 / (4 pi))
    out[1] = c1 * y;
    out[2] = c1 * z;
    out[3] = c1 * x;
  }
  if constexpr (kOrder >= 2) {
    const double c2 = 1.0925484305920792;  // sqrt(15 / (4 pi))
    out[4] = c2 * x * y;
    out[5] = c2 * y * z;
    out[6] = 0.31539156525252005 * (3.0 * z * z - 1.0);  // sqrt(5 / (16 pi))
    out[7] = c2 * x * z;
    out[8] = 0.5462742152960396 * (x * x - y * y);  // sqrt(15 / (16 pi))
  }
  if constexpr (kOrder >= 3) {
    const double a = 0.5900435899266435;  // sqrt(35 / (32 pi))
    const double b = 2.890611442640554;   // sqrt(105 / (4 pi))
    const double c = 0.4570457994644658;  // sqrt(21 / (32 pi))
    const double e = 0.3731763325901154;  // sqrt(7 / (16 pi))
    const double f = 1.445305721320277;   // sqrt(105 / (16 pi))
    out[9] = a * y * (3.0 * x * x - y * y);
    out[10] = b * x * y * z;
    out[11] = c * y * (4.0 * z * z - x * x - y * y);
    out[12] = e * z * (2.0 * z * z - 3.0 * x * x - 3.0 * y * y);
    out[13] = c * x * (4.0 * z * z - x * x - y * y);
    out[14] = f * z * (x * x - y * y);
    out[15] = a * x * (x * x - 3.0 * y * y);
  }
}

}  // namespace

void sh_basis(int order, const Vec3& d, double* out) {
  switch (order) {
    case 1:
      return basis<1>(d, out);
    case 2:
      return basis<2>(d, out);
    case 3:
      return basis<3>(d, out);
    default:
      return basis<0>(d, out);  // order < 1: band 0 only; order > 3 is refused by project_sh
  }
}

double sh_cosine_lobe(int l) {
  switch (l) {
    case 0:
      return kPi;
    case 1:
      return 2.0 * kPi / 3.0;
    case 2:
      return kPi / 4.0;
    default:
      return 0.0;  // l = 3 (and every odd l > 1)
  }
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
  std::array<double, 16> y{};
  sh_basis(order, n, y.data());
  double e = 0.0;
  for (int l = 0; l <= order; ++l)
    for (int m = -l; m <= l; ++m) {
      const int i = l * (l + 1) + m;
      e += sh_cosine_lobe(l) * sh_window_factor(window, l, order) * radiance[channel][i] * y[i];
    }
  return e / kPi;
}

nlohmann::json ShCoefficients::to_json() const {
  nlohmann::json j;
  j["order"] = order;
  j["coefficients_per_channel"] = sh_count(order);
  j["basis"] =
      "real spherical harmonics, orthonormal on the sphere, no "
      "Condon-Shortley phase, index l*(l+1)+m, in the world "
      "direction (x, y, z); envkit/GL world: +Y up";
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

  template <int kOrder>
  void add(int y, double* acc) const {
    constexpr int kCount = (kOrder + 1) * (kOrder + 1);
    const Image& img = src.image;
    double b[kCount];
    for (int x = 0; x < img.width; ++x) {
      Vec3 d;
      if (!coverage.covered(std::size_t(y) * img.width + x) || !dirs.centre(x, y, d)) continue;
      // Texel directions are unit and to_world is a rotation: no normalisation (its square root and divisions
      // were most of this loop's time).
      basis<kOrder>(apply(src.to_world, d), b);
      const double o = omega(x, y);
      const float* px = img.at(x, y);
      for (std::size_t k = 0; k < colour.size(); ++k) {
        const double v = double(px[colour[k]]) * o;
        for (int i = 0; i < kCount; ++i) acc[k * kCount + i] += v * b[i];
      }
    }
  }
};

}  // namespace

ShCoefficients project_sh(const MapRef& src, int order, ShWindow window) {
  if (order < 1 || order > 3) throw Error("SH order must be 1, 2 or 3, not " + std::to_string(order));
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
      default:
        return projection.add<3>(y, rows[y].data());
    }
  });
  sh.radiance.assign(colour.size(), std::vector<double>(count, 0.0));
  for (const auto& row : rows)
    for (std::size_t k = 0; k < colour.size(); ++k)
      for (int i = 0; i < count; ++i) sh.radiance[k][i] += row[k * count + i];
  return sh;
}

}  // namespace envkit
