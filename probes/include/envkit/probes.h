#pragma once
/// @file probes.h
/// Analytic environments with closed-form integrals, their exact rasterization into any parameterization,
/// and envkit's built-in default probe (a procedural outdoor sky).
///
/// Conventions
/// - Directions are unit vectors in the canonical envkit frame (+Y up, see vec.h) pointing from the centre
///   towards what is seen. Radiance is linear RGB in double; "W/sr" below stands for the radiance unit, so a
///   power (integral of L over the sphere) is in radiance x steradian per channel and an irradiance in
///   radiance x steradian weighted by the cosine.
/// - Elevation is the angle above the horizon (the XZ plane). Azimuth is the longitude of latlong.h:
///   0 looks along +Z (centre of a lat-long image), +90 deg along +X, 180 deg along -Z, -90 deg along -X.
/// - Spherical cells (checker) use theta = polar angle from +Y in [0, pi] and the lat-long column coordinate
///   u = (pi - azimuth) / (2 pi) in [0, 1) (u = 0 at -Z, 1/4 at +X, 1/2 at +Z, 3/4 at -X), so lat-long texel
///   rows and columns line up with cells when the image size is a multiple of the cell counts.
///
/// A probe's radiance is split into a background (anything, possibly discontinuous: the probe states where
/// with background_may_vary) plus a few small *features* (a sun disk, one texel of a map): regions of known
/// exact solid angle that add a constant excess radiance. The rasterizer conserves each feature's flux exactly,
/// however small the feature is relative to the texels.
#include <envkit/core/image.h>
#include <envkit/core/vec.h>
#include <envkit/maps/parameterization.h>

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace envkit::probes {

/// Unit direction from elevation and azimuth (radians); see the conventions above.
Vec3 direction_from_elevation_azimuth(double elevation, double azimuth);
/// Solid angle 2 pi (1 - cos alpha) of a cap of angular radius alpha (radians), without cancellation.
double cap_solid_angle(double alpha);
/// Degrees to radians.
constexpr double radians(double degrees) { return degrees * (kPi / 180.0); }
/// Exact solid angle of the lat-long domain rectangle [u0, u1] x [v0, v1] (latlong.h's u, v):
/// 2 pi (u1 - u0) (cos(pi v0) - cos(pi v1)), the difference as LatLongMap::band_height.
double latlong_rect_solid_angle(double u0, double u1, double v0, double v1);
/// True if every channel is finite and >= 0 (what probes accept as radiance).
bool valid_radiance(const Vec3& v);

/// A small region that adds `excess` radiance on top of the background.
struct Feature {
  Vec3 centre;             ///< unit direction inside the region (the disk centre)
  double bound = 0;        ///< the region lies within the cap of this angular radius (rad) around centre
  bool is_disk = false;    ///< the region is exactly that cap (lets the rasterizer skip cells fully inside)
  double solid_angle = 0;  ///< exact solid angle of the region (sr)
  Vec3 excess;             ///< radiance added inside the region (per channel)
  double leaf_radius = 0;  ///< cells near the region's boundary are refined to this angular radius (rad)
};

/// An environment: radiance of a direction, with closed-form integrals.
class Probe {
 public:
  virtual ~Probe() = default;

  /// One line for users, e.g. "sun: 0.265 deg radius at elevation 35 deg, azimuth 45 deg".
  virtual std::string describe() const = 0;

  /// Radiance without the features.
  virtual Vec3 background(const Vec3& dir) const = 0;
  /// Full radiance: background plus the excess of every feature containing dir.
  Vec3 radiance(const Vec3& dir) const;

  /// The features (empty for most probes).
  const std::vector<Feature>& features() const { return features_; }
  /// Whether dir lies inside feature k. Default: inside the cap (centre, bound).
  virtual bool in_feature(std::size_t k, const Vec3& dir) const;

  /// How the background varies, which tells the rasterizer where sampling is needed:
  /// Uniform           the same in every direction (only features are sampled);
  /// PiecewiseUniform  constant except across the discontinuities background_may_vary reports;
  /// Smooth            smooth (cells are split down to RasterOptions::smooth_radius) plus those discontinuities.
  enum class Variation { Uniform, PiecewiseUniform, Smooth };
  virtual Variation background_variation() const { return Variation::Smooth; }
  /// Conservative refinement hint: may the background be discontinuous (or have a kink or a detail narrower
  /// than `radius`) within the cap of angular radius `radius` around dir? Smooth backgrounds return false.
  virtual bool background_may_vary(const Vec3& dir, double radius) const;
  /// Total length (radians of arc) of the curves across which the background jumps, where it grows with the
  /// probe's settings (the checker's parallels and meridians); 0 for probes without such curves. It is what
  /// rasterizing costs beyond one sample per texel (edge_evaluations()).
  virtual double discontinuity_length() const { return 0.0; }

  /// Exact integral of the background over the lat-long domain rectangle u in [u0, u1], v in [v0, v1]
  /// (u, v as in latlong.h: polar angle theta = pi v, azimuth = pi - 2 pi u) in W/sr x sr. Returns false
  /// when the probe has no closed form; the rasterizer then samples.
  virtual bool integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const;

  /// Integral of L over the sphere (per channel, W/sr x sr).
  virtual Vec3 total_power() const = 0;
  /// False when total_power() is a numerical estimate (the default probe).
  virtual bool power_is_closed_form() const { return true; }
  /// Irradiance on a horizontal plane facing +Y: integral of L max(y, 0) d omega, when it has a closed form.
  virtual std::optional<Vec3> upward_irradiance() const { return std::nullopt; }

 protected:
  std::vector<Feature> features_;
};

/// L(dir) = radiance everywhere. Power 4 pi L; upward irradiance pi L.
class ConstantProbe final : public Probe {
 public:
  explicit ConstantProbe(Vec3 radiance);
  std::string describe() const override;
  Vec3 background(const Vec3&) const override { return radiance_; }
  Variation background_variation() const override { return Variation::Uniform; }
  bool integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const override;
  Vec3 total_power() const override;
  std::optional<Vec3> upward_irradiance() const override;

 private:
  Vec3 radiance_;
};

/// Sky gradient with y = dir.y (the sine of the elevation), per channel:
///   Quadratic:   L = base + gain y^2          power 4 pi base + (4 pi / 3) gain, irradiance pi base + (pi/2) gain
///   UpperLinear: L = base + gain max(y, 0)    power 4 pi base + pi gain,         irradiance pi base + (2 pi/3) gain
class GradientProbe final : public Probe {
 public:
  enum class Form { Quadratic, UpperLinear };
  GradientProbe(Vec3 base, Vec3 gain, Form form = Form::UpperLinear);
  std::string describe() const override;
  Vec3 background(const Vec3& dir) const override;
  bool background_may_vary(const Vec3& dir, double radius) const override;
  bool integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const override;
  Vec3 total_power() const override;
  std::optional<Vec3> upward_irradiance() const override;

 private:
  Vec3 base_, gain_;
  Form form_;
};

/// A sun disk of angular radius alpha and radiance `sun` over a uniform sky `sky` (the disk replaces the sky):
/// power = sun 2 pi (1 - cos alpha) + sky (4 pi - 2 pi (1 - cos alpha)). Upward irradiance is closed-form
/// while the disk lies wholly above or below the horizon: pi sky + (sun - sky) pi sin^2(alpha) sin(elevation).
class SunProbe final : public Probe {
 public:
  /// `direction` any non-zero vector; alpha in radians, in (0, pi/2]. Throws Error on bad arguments.
  SunProbe(Vec3 direction, double alpha, Vec3 sun, Vec3 sky);
  std::string describe() const override;
  Vec3 background(const Vec3&) const override { return sky_; }
  Variation background_variation() const override { return Variation::Uniform; }
  bool integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const override;
  Vec3 total_power() const override;
  std::optional<Vec3> upward_irradiance() const override;
  const Vec3& direction() const { return features_[0].centre; }

 private:
  double alpha_;
  Vec3 sun_, sky_;
};

/// One texel (i, j) of a map has radiance `value`, every other direction `floor`. Defined by the map: as a
/// direction function, "inside" means map.to_image(dir) falls in texel (i, j), so it can be rasterized into
/// the same map (exact) or into any other one (flux exact). power = value Omega + floor (4 pi - Omega) with
/// Omega = map.texel_solid_angle(i, j) exactly.
class TexelProbe final : public Probe {
 public:
  /// Throws Error if (i, j) is outside the map or holds no data.
  TexelProbe(const Parameterization& map, int i, int j, Vec3 value, Vec3 floor);
  std::string describe() const override;
  Vec3 background(const Vec3&) const override { return floor_; }
  Variation background_variation() const override { return Variation::Uniform; }
  bool in_feature(std::size_t k, const Vec3& dir) const override;
  bool integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const override;
  Vec3 total_power() const override;
  std::optional<Vec3> upward_irradiance() const override { return std::nullopt; }

 private:
  std::unique_ptr<Parameterization> map_;
  int i_, j_;
  Vec3 value_, floor_;
};

/// n_theta x n_phi cells in (theta, u) alternating two colours: cell (a, b) with a = floor(theta n_theta / pi),
/// b = floor(u n_phi) has colour_a when a + b is even. Each cell has the exact solid angle
/// (2 pi / n_phi)(cos theta0 - cos theta1), so power and upward irradiance are exact sums.
class CheckerProbe final : public Probe {
 public:
  CheckerProbe(int n_theta, int n_phi, Vec3 colour_a, Vec3 colour_b);
  std::string describe() const override;
  Vec3 background(const Vec3& dir) const override;
  Variation background_variation() const override { return Variation::PiecewiseUniform; }
  bool background_may_vary(const Vec3& dir, double radius) const override;
  /// The parallels between bands, 2 pi cot(pi / (2 n_theta)) in all, and the meridians between cells of
  /// different colours, pi each (the seam too when n_phi is even); 0 when the two colours are equal.
  double discontinuity_length() const override;
  bool integrate_latlong(double u0, double u1, double v0, double v1, Vec3& integral) const override;
  Vec3 total_power() const override;
  std::optional<Vec3> upward_irradiance() const override;

 private:
  const Vec3& colour(int a, int b) const { return ((a + b) & 1) == 0 ? colour_a_ : colour_b_; }
  int n_theta_, n_phi_;
  Vec3 colour_a_, colour_b_;
};

/// Settings of the built-in outdoor probe. Angles in degrees.
struct OutdoorSettings {
  double sun_elevation_deg = 35.0;
  /// Between +Z (0) and +X (90); not 45, which falls on a texel edge of every power-of-two lat-long.
  double sun_azimuth_deg = 40.0;
  double sun_radius_deg = 0.27;
  Vec3 sun_radiance{3.2e4, 3.0e4, 2.7e4};  ///< added on top of the sky inside the disk
  std::uint32_t seed = 7;                  ///< cloud noise seed
  double cloud_cover = 0.35;               ///< 0 = clear sky, 1 = overcast
};

/// envkit's default probe: a procedural outdoor sky, deterministic for given settings.
/// - Sky: deep blue zenith to a bright hazy horizon (~0.3-1.6), a glow around the sun, soft value-noise clouds
///   on a perspective cloud layer that thin out towards the horizon.
/// - Sun: a disk (feature) of radius 0.27 deg adding ~3e4 at elevation 35 deg, azimuth 40 deg.
/// - Ground below the horizon: brown, with a perspective checker of 2-unit tiles (viewer 1 unit above the
///   ground) aligned with the X and Z axes, fading into haze at the horizon.
/// - Silhouettes on the horizon: a mountain range at azimuths -80..-10 deg (between -X and +Z, up to 10 deg
///   high) and a block skyline at azimuths 110..170 deg (between +X and -Z, up to ~6 deg high).
/// - Orientation markers: disks of radius 2 deg at elevation 3 deg: red at +X, green at +Z, blue at -X.
/// total_power() is numerical (a 512x256 rasterization, cached), about 1e-4 relative.
class OutdoorProbe final : public Probe {
 public:
  explicit OutdoorProbe(OutdoorSettings settings = {});
  std::string describe() const override;
  Vec3 background(const Vec3& dir) const override;
  bool background_may_vary(const Vec3& dir, double radius) const override;
  Vec3 total_power() const override;
  bool power_is_closed_form() const override { return false; }
  const OutdoorSettings& settings() const { return settings_; }
  const Vec3& sun_direction() const { return features_[0].centre; }

 private:
  Vec3 sky(const Vec3& dir) const;
  Vec3 ground(const Vec3& dir) const;
  OutdoorSettings settings_;
  mutable std::once_flag power_once_;
  mutable Vec3 power_{0, 0, 0};
};

/// The built-in default probe (OutdoorProbe with default settings).
std::unique_ptr<Probe> make_default_probe();

/// Controls of the rasterizer's adaptive supersampling. A cell is split (into 2 x 2 in image space) while
/// - its angular radius exceeds smooth_radius (and its solid angle that of a cell of that radius), at most
///   max_levels below the texel;
/// - the probe's background may vary inside it and its radius exceeds the texel's edge leaf radius
///   min(texel radius / 2^edge_levels, edge_radius) (and its solid angle that of such a cell), at most
///   max_edge_levels below the texel; such leaves are then sampled with 16 Hammersley points;
/// - it is partly without data (a rim), at most max_partial_levels below the texel;
/// - it straddles a feature's boundary and its radius exceeds the feature's leaf_radius, at most
///   max_feature_depth below the texel.
/// Other leaves are sampled at their centre, weighted by their exact solid angle. The solid-angle guards stop
/// refinement where a map is singular (a mirror ball's rim): there cells are long but carry almost no solid
/// angle.
struct RasterOptions {
  /// Maps directions of the target's map frame to the canonical world frame (see convention.h).
  Mat3 map_to_world = identity3();
  double smooth_radius = radians(0.5);
  int max_levels = 10;
  int edge_levels = 3;
  double edge_radius = radians(0.25);
  int max_edge_levels = 12;
  int max_partial_levels = 6;
  int max_feature_depth = 24;
  /// Use the probe's exact lat-long rectangle integrals when the target is a LatLongMap.
  bool exact_latlong = true;
  /// Add an alpha channel (1 where the texel holds data, 0 elsewhere) to the image rasterize() returns.
  bool alpha = false;
};

/// What the rasterizer did with each feature.
struct FeatureStats {
  double target = 0;    ///< exact solid angle of the feature
  double sampled = 0;   ///< solid angle found by supersampling (before rescaling)
  double scale = 1;     ///< target / sampled
  bool missed = false;  ///< no subsample hit it: the whole flux went to the texel containing its centre
  bool lost = false;    ///< that texel holds no data: the feature's flux is missing from the map
};
struct RasterStats {
  std::vector<FeatureStats> features;
};

/// Rasterizes a probe into a new RGB (or RGBA with options.alpha) image of the parameterization's size:
/// each texel holds the average radiance over its solid angle, (1 / Omega_texel) x integral of L. Texels
/// without data stay 0 (alpha 0). Parallel over rows; the result does not depend on the thread count.
Image rasterize(const Probe& probe, const Parameterization& map, const RasterOptions& options = {},
                RasterStats* stats = nullptr);
/// Same into an existing image of the map's size: the first three colour channels get R, G, B (a single
/// colour channel gets Rec. 709 luminance), further colour channels 0, the alpha channel (if any) coverage.
void rasterize_into(const Probe& probe, const Parameterization& map, Image& image, const RasterOptions& options = {},
                    RasterStats* stats = nullptr);

/// About how many background evaluations rasterize() spends resolving the probe's discontinuities
/// (Probe::discontinuity_length()) on `map`: the leaves of edge_levels refinement that a curve of that length
/// crosses, each sampled 16 times, at most every leaf of every texel; 0 where rasterize() integrates the
/// probe exactly (a lat-long map in its own frame, a probe with lat-long integrals). An estimate, good to a
/// small factor, for checking the cost of a request before rasterizing.
double edge_evaluations(const Probe& probe, const Parameterization& map, const RasterOptions& options = {});

/// Sum over texels of L_texel x texel_solid_angle (per channel, double accumulation): the power a map holds.
/// A one-colour-channel image gives (Y, Y, Y).
Vec3 image_power(const Image& image, const Parameterization& map);

}  // namespace envkit::probes
