#include <envkit/core/gauss_legendre.h>
#include <envkit/core/vec.h>

#include <cmath>
#include <memory>

namespace envkit::detail {

const GaussLegendre& gauss_legendre(int n) {
  thread_local std::vector<std::unique_ptr<GaussLegendre>> cache;
  for (const auto& g : cache)
    if (g->n == n) return *g;
  auto g = std::make_unique<GaussLegendre>();
  g->n = n;
  g->x.assign(n, 0.0);
  g->w.assign(n, 0.0);
  for (int i = 0; i < (n + 1) / 2; ++i) {
    double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 1.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = 0.0;
      for (int k = 1; k <= n; ++k) {
        const double p2 = p1;
        p1 = p0;
        p0 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p2) / k;
      }
      dp = n * (z * p0 - p1) / (z * z - 1.0);
      const double dz = p0 / dp;
      z -= dz;
      if (std::abs(dz) < 1e-15) break;
    }
    const double weight = 1.0 / ((1.0 - z * z) * dp * dp);  // on [-1, 1]: 2 / ((1 - z^2) P'^2); halved for [0, 1]
    g->x[i] = 0.5 * (1.0 - z);
    g->x[n - 1 - i] = 0.5 * (1.0 + z);
    g->w[i] = g->w[n - 1 - i] = weight;
  }
  cache.push_back(std::move(g));
  return *cache.back();
}

}  // namespace envkit::detail
