#pragma once
// Gauss-Legendre quadrature on an interval, for any number of nodes: the one home of the rule in libenv.
#include <vector>

namespace envkit::detail {

struct GaussLegendre {
  int n = 0;
  std::vector<double> x, w;  // nodes in (0, 1) and weights summing to 1
};

// The n-node rule on [0, 1] (Newton on P_n from the Chebyshev guesses); cached per thread and n, so the reference
// stays valid for the thread's lifetime.
const GaussLegendre& gauss_legendre(int n);

// Calls f(x, weight) for the n Gauss-Legendre nodes of [a, b] (nothing when b <= a); the weights sum to b - a.
template <class F>
void for_nodes(double a, double b, int n, F&& f) {
  if (!(b > a)) return;
  const GaussLegendre& g = gauss_legendre(n);
  for (int i = 0; i < n; ++i) f(a + (b - a) * g.x[i], (b - a) * g.w[i]);
}

}  // namespace envkit::detail
