#include <envkit/core/error.h>
#include <envkit/sampling/haar.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

namespace envkit::haar {

namespace {

void check(std::size_t size, int R) {
  if (!valid_size(R) || size != std::size_t(R) * std::size_t(R))
    throw Error("haar: a " + std::to_string(R) + " x " + std::to_string(R) + " grid (power of two >= 2) of " +
                std::to_string(std::size_t(R) * std::size_t(R)) + " values expected, got " + std::to_string(size));
}

/// One step of block size n: the n x n top-left block of values becomes scaling coefficients and details.
void forward_step(std::span<double> v, int R, int n, std::vector<double>& block) {
  const int h = n / 2;
  block.assign(std::size_t(n) * std::size_t(n), 0.0);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < h; ++i) {
      const double a = v[std::size_t(2 * j) * R + 2 * i], b = v[std::size_t(2 * j) * R + 2 * i + 1];
      const double c = v[std::size_t(2 * j + 1) * R + 2 * i], d = v[std::size_t(2 * j + 1) * R + 2 * i + 1];
      block[std::size_t(j) * n + i] = 0.5 * (a + b + c + d);
      block[std::size_t(j) * n + i + h] = 0.5 * (a - b + c - d);
      block[std::size_t(j + h) * n + i] = 0.5 * (a + b - c - d);
      block[std::size_t(j + h) * n + i + h] = 0.5 * (a - b - c + d);
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) v[std::size_t(j) * R + i] = block[std::size_t(j) * n + i];
}

void inverse_step(std::span<double> c, int R, int n, std::vector<double>& block) {
  const int h = n / 2;
  block.assign(std::size_t(n) * std::size_t(n), 0.0);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < h; ++i) {
      const double s = c[std::size_t(j) * R + i], dx = c[std::size_t(j) * R + i + h];
      const double dy = c[std::size_t(j + h) * R + i], dd = c[std::size_t(j + h) * R + i + h];
      block[std::size_t(2 * j) * n + 2 * i] = 0.5 * (s + dx + dy + dd);
      block[std::size_t(2 * j) * n + 2 * i + 1] = 0.5 * (s - dx + dy - dd);
      block[std::size_t(2 * j + 1) * n + 2 * i] = 0.5 * (s + dx - dy - dd);
      block[std::size_t(2 * j + 1) * n + 2 * i + 1] = 0.5 * (s - dx - dy + dd);
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) c[std::size_t(j) * R + i] = block[std::size_t(j) * n + i];
}

}  // namespace

bool valid_size(int R) { return R >= 2 && R <= (1 << 15) && (R & (R - 1)) == 0; }

void forward(std::span<double> v, int R) {
  check(v.size(), R);
  std::vector<double> block;
  for (int n = R; n >= 2; n /= 2) forward_step(v, R, n, block);
}

void inverse(std::span<double> c, int R) {
  check(c.size(), R);
  std::vector<double> block;
  for (int n = 2; n <= R; n *= 2) inverse_step(c, R, n, block);
}

std::size_t keep_largest(std::span<double> c, int R, int keep) {
  check(c.size(), R);
  const std::size_t details = c.size() - 1;
  if (keep > 0 && std::size_t(keep) < details) {
    std::vector<std::size_t> order(details);
    std::iota(order.begin(), order.end(), std::size_t(1));
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t x, std::size_t y) { return std::abs(c[x]) > std::abs(c[y]); });
    for (std::size_t k = std::size_t(keep); k < details; ++k) c[order[k]] = 0.0;
  }
  return std::size_t(std::count_if(c.begin(), c.end(), [](double x) { return x != 0.0; }));
}

std::vector<std::vector<double>> product_sums(std::span<const double> a, std::span<const double> b, int R) {
  check(a.size(), R);
  check(b.size(), R);
  int levels = 0;
  while ((1 << levels) < R) ++levels;
  // Scaling coefficients of every node, top-down (the inverse transform's intermediate blocks).
  std::vector<double> ca(a.begin(), a.end()), cb(b.begin(), b.end());
  std::vector<std::vector<double>> sa(std::size_t(levels) + 1), sb(std::size_t(levels) + 1);
  std::vector<double> block;
  const auto keep_block = [R](const std::vector<double>& c, int m) {
    std::vector<double> s(std::size_t(m) * std::size_t(m));
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) s[std::size_t(j) * m + i] = c[std::size_t(j) * R + i];
    return s;
  };
  sa[std::size_t(levels)] = {ca[0]};
  sb[std::size_t(levels)] = {cb[0]};
  for (int n = 2, k = levels - 1; n <= R; n *= 2, --k) {
    inverse_step(ca, R, n, block);
    inverse_step(cb, R, n, block);
    sa[std::size_t(k)] = keep_block(ca, n);
    sb[std::size_t(k)] = keep_block(cb, n);
  }
  // Detail products summed bottom-up over each node's subtree; the node's sum adds its scaling product.
  std::vector<std::vector<double>> sums(std::size_t(levels) + 1);
  std::vector<double> detail(std::size_t(R) * std::size_t(R), 0.0);  // subtree detail sums of the level below
  sums[0].resize(detail.size());
  for (std::size_t c = 0; c < detail.size(); ++c) sums[0][c] = sa[0][c] * sb[0][c];
  for (int k = 1; k <= levels; ++k) {
    const int m = R >> k, below = 2 * m;
    std::vector<double> here(std::size_t(m) * std::size_t(m));
    sums[std::size_t(k)].resize(here.size());
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i) {
        const std::size_t x = std::size_t(j) * R + i + m, y = std::size_t(j + m) * R + i,
                          d = std::size_t(j + m) * R + i + m;
        double s = a[x] * b[x] + a[y] * b[y] + a[d] * b[d];
        for (int dy = 0; dy < 2; ++dy)
          for (int dx = 0; dx < 2; ++dx) s += detail[std::size_t(2 * j + dy) * below + 2 * i + dx];
        here[std::size_t(j) * m + i] = s;
        const std::size_t node = std::size_t(j) * m + i;
        sums[std::size_t(k)][node] = sa[std::size_t(k)][node] * sb[std::size_t(k)][node] + s;
      }
    detail = std::move(here);
  }
  return sums;
}

}  // namespace envkit::haar
