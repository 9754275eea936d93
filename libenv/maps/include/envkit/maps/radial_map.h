#pragma once
/// @file radial_map.h
/// Shared machinery of the maps that hold one or two disks in which the angle from the disk's axis depends
/// only on the distance from the disk's centre: mirror ball, angular map, dual paraboloid.
///
/// Inside a disk, with normalized coordinates (x, y) = ((px - cx) / R, (cy - py) / R) (y up) and r = |(x, y)|,
/// the direction is  cos(theta) axis + sin(theta) (x right + y up) / r  with theta = polar_angle(r).
///
/// Exact solid angle: on the sphere, d(omega) = d((1 - cos theta) d phi), so by Green's theorem the solid angle of
/// any image region is the boundary integral of G(r) d phi with G(r) = 1 - cos(polar_angle(min(r, 1))).
/// Extending G as a constant beyond the rim makes the 2-form vanish outside the disk, so the integral over the
/// boundary of a texel directly gives the solid angle of texel-inside-disk: no polygon clipping. Along a
/// straight edge p(t) = p0 + t (p1 - p0), d phi = (p0 x p1) dt / r(t)^2, so each edge contributes
/// (p0 x p1) * integral of G(r)/r^2 dt: a smooth integrand inside the disk (Gauss-Legendre on pieces split
/// at the rim) and the exact swept angle times G(1) outside it.
#include <envkit/maps/parameterization.h>

#include <vector>

namespace envkit {

/// One disk in the image, in pixels, with the frame of the directions it shows.
struct Disk {
  double cx = 0, cy = 0, radius = 1;  ///< centre and radius in continuous image coordinates
  Vec3 axis, right, up;               ///< direction at the centre; image-right and image-up at the centre
};

/// The equidistant lens, polar angle theta = k r (k: the polar angle on the rim, radians), shared by the angular map
/// (k = pi), the sky angular map (k = pi / 2) and equidistant fisheyes (k = fov / 2): RadialMap's cap_density,
/// (1 - cos(k r)) / r^2 = 2 sin^2(k r / 2) / r^2, and area_density, k sin(k r) / r; both finite at r = 0.
double equidistant_cap_density(double r, double k);
double equidistant_area_density(double r, double k);

class RadialMap : public Parameterization {
 public:
  bool to_direction(Vec2 pos, Vec3& dir) const override;
  Vec2 to_image(const Vec3& dir) const override;
  bool covered_point(int i, int j, Vec2& pos) const override;
  double solid_angle(double x0, double y0, double x1, double y1) const override;
  double solid_angle_density(Vec2 pos) const override;
  /// Same kind and size, and the same disks (centres, radii and frames).
  bool same_grid(const Parameterization& other) const override;
  /// The corners outside the disks hold no data.
  bool has_blank_texels() const override { return true; }

  const std::vector<Disk>& disks() const { return disks_; }

  /// Angle from the disk axis at normalized radius r (r in [0, 1] inside the disk).
  virtual double polar_angle(double r) const = 0;
  /// Normalized radius at which the angle from the axis is theta.
  virtual double radius_of_angle(double theta) const = 0;

 protected:
  RadialMap(int width, int height) : Parameterization(width, height) {}
  /// (1 - cos polar_angle(r)) / r^2 for r in [0, 1]; smooth, finite at r = 0.
  virtual double cap_density(double r) const = 0;
  /// d(omega)/dA on the unit disk at normalized radius r: polar_angle'(r) sin(polar_angle(r)) / r.
  virtual double area_density(double r) const = 0;
  /// Which disk shows `dir` (for two disks: the hemisphere it lies in).
  virtual int disk_for_direction(const Vec3& dir) const;
  /// Index of the disk containing image position pos (r <= 1), or -1.
  int disk_at(Vec2 pos) const;

  std::vector<Disk> disks_;

 private:
  double disk_solid_angle(const Disk& disk, double x0, double y0, double x1, double y1) const;
  double edge_integral(double ax, double ay, double bx, double by) const;
};

}  // namespace envkit
