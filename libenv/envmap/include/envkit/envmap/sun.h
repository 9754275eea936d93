#pragma once
/// @file sun.h
/// Finding the sun in an environment map: the small, very bright region that carries a large share of a map's
/// light and that renderers do better to sample as a light of its own (an analytic disk) than through the map.
///
/// What counts as the sun: the brightest texel and the texels around it (within `search_radius`) whose luminance
/// is at least the geometric mean of that peak and the map's median luminance (halfway between sky and sun on a
/// log scale: a sun's partly covered edge texels are in, the circumsolar glow mostly out). The region is a sun when
/// it is small (a disk of at most `max_radius`), outshines the median by `min_contrast` and carries at least
/// `min_power_share` of the map's luminance power. Parameterization-independent: texels are compared by their
/// world directions and exact solid angles, never by image adjacency (a sun on a cube edge is one region).
#include <envkit/core/vec.h>
#include <envkit/envmap/envmap.h>

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace envkit {

struct SunOptions {
  double search_radius = 10.0 * kPi / 180;  ///< texels farther than this from the brightest one are never the sun (rad)
  double max_radius = 3.0 * kPi / 180;      ///< angular radius of a disk of the region's solid angle, at most (rad)
  double min_contrast = 1000.0;             ///< peak luminance / median luminance, at least
  double min_power_share = 0.01;            ///< the region's share of the map's luminance power, at least
  /// A flat top (several texels at exactly the region's largest value) is taken for a clipped sun only when the
  /// peak is below this multiple of the median: a disk of uniform radiance (an analytic or rendered sun) is flat
  /// too, but real suns are 1e5-1e6 times their sky, and a camera's clipping level is far below that.
  double clipped_contrast = 1e4;
  std::string colorspace = "scene_linear";  ///< colour space of the pixels, for the luminance weights
};

struct SunEstimate {
  Vec3 direction;                    ///< world frame (envkit: +Y up), unit: the luminance-flux centroid of the region
  double solid_angle = 0.0;          ///< sr, sum of the region's exact texel solid angles
  double angular_radius = 0.0;       ///< rad, of the disk with that solid angle: acos(1 - solid_angle / 2 pi). A map
                                     ///< cannot resolve a sun smaller than its texels: this is then the texels' size.
  std::array<double, 3> power{};     ///< per colour channel, sum of L x solid angle over the region (W/sr x sr)
  std::array<double, 3> radiance{};  ///< power / solid_angle: the disk's mean radiance
  double power_share = 0.0;          ///< the region's share of the map's luminance power, in [0, 1]
  double peak_luminance = 0.0;       ///< the brightest texel's luminance
  double median_luminance = 0.0;     ///< the map's median texel luminance
  int texels = 0;                    ///< texels in the region
  /// Several texels share the region's maximum value exactly: the camera clipped the sun, whose power in the
  /// map is then too low (often by orders of magnitude).
  bool clipped = false;
  int clipped_texels = 0;
  /// The region's texels: indices y * width + x into the map's image, ascending.
  std::vector<std::size_t> region;
};

/// The sun of `map`, or nothing when the map has none by the rules above. Colour channels are the first three
/// non-alpha channels (one channel: used for all three). Deterministic; NaN, Inf and negative values count as 0.
std::optional<SunEstimate> detect_sun(const EnvMap& map, const SunOptions& options = {});

}  // namespace envkit
