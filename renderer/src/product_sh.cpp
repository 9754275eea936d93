#include <envkit/core/gauss_legendre.h>
#include <envkit/core/sh_basis.h>
#include <envkit/render/product_sh.h>
#include <envkit/render/product_wavelet.h>
#include <tbb/parallel_for.h>

#include <cmath>

namespace envkit::render {

namespace {

/// Points per side of a finest cell for its integrals of the basis functions (equal-area: equal weights).
constexpr int kCellPointsPerSide = 4;

/// The integrals of every Y_k over every finest cell of the sphere's square (midpoint rule on S x S sub-cells).
std::vector<double> basis_cell_integrals(int order, int R) {
  const std::size_t K = std::size_t(sh_count(order));
  const int S = kCellPointsPerSide;
  const double weight = kFourPi / (double(R) * R * S * S);
  std::vector<double> finest(std::size_t(R) * std::size_t(R) * K, 0.0);
  tbb::parallel_for(0, R, [&](int cy) {
    std::vector<double> y(K);
    for (int cx = 0; cx < R; ++cx) {
      double* cell = finest.data() + (std::size_t(cy) * std::size_t(R) + std::size_t(cx)) * K;
      for (int sy = 0; sy < S; ++sy)
        for (int sx = 0; sx < S; ++sx) {
          const Vec3 d = cap_from_square(Vec2((cx + (sx + 0.5) / S) / R, (cy + (sy + 0.5) / S) / R), kWholeSphere);
          sh_basis(order, d, y.data());
          for (std::size_t k = 0; k < K; ++k) cell[k] += weight * y[k];
        }
    }
  });
  return finest;
}

/// The lighting's importance projected onto SH: sum over pyramid nodes of energy x Y_i(centre).
std::vector<double> project_lighting(const SphericalDistribution& env, int order, int R) {
  const std::size_t K = std::size_t(sh_count(order));
  std::vector<double> lambda(K, 0.0), y(K);
  for (const EnvNode& n : environment_nodes(env, 8 * R, "product-sh")) {
    sh_basis(order, n.centre / n.centre.length(), y.data());
    for (std::size_t i = 0; i < K; ++i) lambda[i] += n.energy * y[i];
  }
  return lambda;
}

/// M_kj = integral of Y_k Y_j lambda over the sphere: Gauss-Legendre in z and equispaced longitudes, exact for the
/// integrand's degree 3 x order.
std::vector<double> lighting_product_matrix(const std::vector<double>& lambda, int order) {
  const std::size_t K = lambda.size();
  const int nz = (3 * order) / 2 + 2, nphi = 3 * order + 2;
  std::vector<double> m(K * K, 0.0), y(K);
  detail::for_nodes(-1.0, 1.0, nz, [&](double z, double wz) {
    const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
    for (int p = 0; p < nphi; ++p) {
      const double phi = kTwoPi * p / nphi, w = wz * kTwoPi / nphi;
      sh_basis(order, Vec3(s * std::cos(phi), s * std::sin(phi), z), y.data());
      double l = 0.0;
      for (std::size_t i = 0; i < K; ++i) l += lambda[i] * y[i];
      for (std::size_t k = 0; k < K; ++k)
        for (std::size_t j = 0; j < K; ++j) m[k * K + j] += w * l * y[k] * y[j];
    }
  });
  return m;
}

}  // namespace

ProductSh::ProductSh(const SphericalDistribution& env, const std::vector<const Material*>& materials,
                     const BasisProductOptions& options)
    : options_(options), env_(&env) {
  check_options(options_, "product-sh");
  lighting_ = project_lighting(env, options_.order, options_.resolution);
  matrix_ = lighting_product_matrix(lighting_, options_.order);
  cells_ = BasisHierarchy(options_.resolution, sh_count(options_.order),
                          basis_cell_integrals(options_.order, options_.resolution));
  fit_ = BsdfLobeFit(materials, options_.order, options_.wo_bins);
}

BasisProductPoint ProductSh::at(const Vec3& normal, const Vec3& wo, const Material& material) const {
  const std::size_t K = lighting_.size();
  std::vector<double> c(K), p(K, 0.0);
  fit_.coefficients(material, normal, wo, c.data());
  for (std::size_t k = 0; k < K; ++k) {
    double s = 0.0;
    for (std::size_t j = 0; j < K; ++j) s += matrix_[k * K + j] * c[j];
    p[k] = s;
  }
  return BasisProductPoint(cells_, std::move(p), *env_, options_.defensive);
}

}  // namespace envkit::render
