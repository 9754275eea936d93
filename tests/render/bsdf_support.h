#pragma once
/// @file bsdf_support.h
/// Shared by the material tests: a grid of cells on the sphere in (z = cos theta, phi), whose area in (z, phi) IS
/// solid angle (integrating a density over a cell needs no Jacobian), adaptive quadrature of a density over its
/// cells (the expected counts of chi-square tests), and directions by angle.
#include <envkit/core/vec.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

namespace envkit::render::bsdf_test {

struct SphereGrid {
  int nz = 24;    // rows over z in [-1, 1]
  int nphi = 48;  // columns over phi in [0, 2 pi)
  int cells() const { return nz * nphi; }
  int cell_of(const Vec3& w) const {
    const double z = std::clamp(w.z, -1.0, 1.0);
    double phi = std::atan2(w.y, w.x);
    if (phi < 0.0) phi += kTwoPi;
    const int iz = std::min(int((z + 1.0) * 0.5 * nz), nz - 1);
    const int ip = std::min(int(phi / kTwoPi * nphi), nphi - 1);
    return iz * nphi + ip;
  }
};

inline Vec3 direction_zphi(double z, double phi) {
  const double r = safe_sqrt(1.0 - z * z);
  return Vec3(r * std::cos(phi), r * std::sin(phi), z);
}

// 2x2 Gauss-Legendre rule on a rectangle of (z, phi).
inline double gauss4(const std::function<double(const Vec3&)>& f, double z0, double z1, double p0, double p1) {
  constexpr double g = 0.57735026918962576;  // 1/sqrt(3)
  const double zc = 0.5 * (z0 + z1), zh = 0.5 * (z1 - z0), pc = 0.5 * (p0 + p1), ph = 0.5 * (p1 - p0);
  double s = 0.0;
  for (double a : {-g, g})
    for (double b : {-g, g}) s += f(direction_zphi(zc + a * zh, pc + b * ph));
  return s * zh * ph;
}

// Adaptive quadrature of f over a (z, phi) rectangle: a 2x2 Gauss estimate is refined into four children until the
// children agree with the parent within max(tol, 1e-5 x the estimate) or depth runs out.
inline double adaptive(const std::function<double(const Vec3&)>& f, double z0, double z1, double p0, double p1,
                       double whole, double tol, int depth) {
  const double zm = 0.5 * (z0 + z1), pm = 0.5 * (p0 + p1);
  const double a = gauss4(f, z0, zm, p0, pm), b = gauss4(f, zm, z1, p0, pm), c = gauss4(f, z0, zm, pm, p1),
               d = gauss4(f, zm, z1, pm, p1);
  const double refined = a + b + c + d;
  if (depth <= 0 || std::abs(refined - whole) <= std::max(tol, 1e-5 * std::abs(refined))) return refined;
  return adaptive(f, z0, zm, p0, pm, a, 0.25 * tol, depth - 1) + adaptive(f, zm, z1, p0, pm, b, 0.25 * tol, depth - 1) +
         adaptive(f, z0, zm, pm, p1, c, 0.25 * tol, depth - 1) + adaptive(f, zm, z1, pm, p1, d, 0.25 * tol, depth - 1);
}

// Integral of f over every grid cell: each cell is pre-split into pre x pre pieces (so that narrow lobes are seen by
// the first estimate) and then refined adaptively, at most `depth` times (a piecewise-constant density refines to
// the full depth along each of its steps: a tabulated pdf needs a smaller depth to finish in seconds).
inline std::vector<double> integrate_cells(const SphereGrid& grid, const std::function<double(const Vec3&)>& f,
                                           double tol_per_cell, int pre = 8, int depth = 10) {
  std::vector<double> out(std::size_t(grid.cells()), 0.0);
  for (int iz = 0; iz < grid.nz; ++iz)
    for (int ip = 0; ip < grid.nphi; ++ip) {
      const double z0 = -1.0 + 2.0 * iz / grid.nz, z1 = -1.0 + 2.0 * (iz + 1) / grid.nz;
      const double p0 = kTwoPi * ip / grid.nphi, p1 = kTwoPi * (ip + 1) / grid.nphi;
      double sum = 0.0;
      for (int a = 0; a < pre; ++a)
        for (int b = 0; b < pre; ++b) {
          const double za = z0 + (z1 - z0) * a / pre, zb = z0 + (z1 - z0) * (a + 1) / pre;
          const double pa = p0 + (p1 - p0) * b / pre, pb = p0 + (p1 - p0) * (b + 1) / pre;
          sum += adaptive(f, za, zb, pa, pb, gauss4(f, za, zb, pa, pb), tol_per_cell / (pre * pre), depth);
        }
      out[std::size_t(iz) * std::size_t(grid.nphi) + std::size_t(ip)] = sum;
    }
  return out;
}

inline Vec3 wo_at(double theta_deg, double phi_deg = 30.0) {
  const double t = theta_deg * kPi / 180.0, p = phi_deg * kPi / 180.0;
  return Vec3(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t));
}

inline bool finite3(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace envkit::render::bsdf_test
