#include <envkit/core/sh_basis.h>
#include <envkit/render/product_steerable.h>
#include <envkit/render/product_wavelet.h>

namespace envkit::render {

namespace {

/// Cell index of a square position, clamped to the grid (NaN -> 0).
int cell_of(double t, int n) { return t > 0.0 ? std::min(int(t * n), n - 1) : 0; }

/// T_k(cell): the lighting's importance times Y_k at each pyramid node's centre, summed over the finest cells.
std::vector<double> lighting_tables(const SphericalDistribution& env, int order, int R) {
  const std::size_t K = std::size_t(sh_count(order));
  std::vector<double> finest(std::size_t(R) * std::size_t(R) * K, 0.0), y(K);
  for (const EnvNode& n : environment_nodes(env, 8 * R, "product-steerable")) {
    const Vec2 uv = square_from_cap(n.centre, kWholeSphere);
    const std::size_t cell = std::size_t(cell_of(uv.y, R)) * std::size_t(R) + std::size_t(cell_of(uv.x, R));
    sh_basis(order, n.centre / n.centre.length(), y.data());
    for (std::size_t k = 0; k < K; ++k) finest[cell * K + k] += n.energy * y[k];
  }
  return finest;
}

}  // namespace

ProductSteerable::ProductSteerable(const SphericalDistribution& env, const std::vector<const Material*>& materials,
                                   const BasisProductOptions& options)
    : options_(options), env_(&env) {
  check_options(options_, "product-steerable");
  tables_ = BasisHierarchy(options_.resolution, sh_count(options_.order),
                           lighting_tables(env, options_.order, options_.resolution));
  fit_ = BsdfLobeFit(materials, options_.order, options_.wo_bins);
}

BasisProductPoint ProductSteerable::at(const Vec3& normal, const Vec3& wo, const Material& material) const {
  std::vector<double> c(std::size_t(sh_count(options_.order)));
  fit_.coefficients(material, normal, wo, c.data());
  return BasisProductPoint(tables_, std::move(c), *env_, options_.defensive);
}

}  // namespace envkit::render
