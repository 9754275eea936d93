#pragma once
/// @file view.h
/// What a camera view (perspective.h, fisheye.h) needs beside its lens: where
/// it looks, its roll, its field of view, and how those are written into a
/// file's metadata (envkit:view) so that the tools re-read them.
///
/// Camera frame: `forward` is the viewing direction (map frame). With roll 0,
/// image up is the part of the map frame's +Y perpendicular to forward (for a
/// view straight up or down, image up is -Z resp. +Z instead), and image right
/// is forward x up: looking along +Z with +Y up, image right is -X, as envkit's
/// world has it (vec.h). A positive roll turns the camera counter-clockwise
/// about forward, so the picture turns clockwise.
#include <envkit/core/vec.h>

#include <string>

namespace envkit {

/// Fisheye lens projections: r = f(theta), theta the angle from the optical
/// axis, r normalised to 1 at the image circle (theta = fov / 2).
enum class Lens {
  Equidistant,    ///< r proportional to theta (fov up to 360)
  Equisolid,      ///< r proportional to sin(theta / 2): equal-area (fov up to 360)
  Orthographic,   ///< r proportional to sin(theta) (fov up to 180)
  Stereographic,  ///< r proportional to tan(theta / 2) (fov below 360)
};
std::string lens_name(Lens lens);
/// "equidistant", "equisolid", "orthographic", "stereographic" (also
/// "equal-area", "ortho", "stereo"). Throws Error.
Lens parse_lens(const std::string& name);

/// The narrowest field of view a camera view accepts, in degrees (0.0036 arcseconds, far below any camera or
/// telescope). Narrower views would have texel solid angles near float's smallest normal number at the largest
/// image sizes, where the resampler's float tables lose them and the view comes out black.
inline constexpr double kMinFovDegrees = 1e-6;

/// Which image extent `fov_degrees` spans for a perspective view.
enum class FovAxis { Horizontal, Vertical };

struct ViewParams {
  Vec3 forward = Vec3(0, 0, 1);  ///< viewing direction, map frame (any non-zero length)
  double roll_degrees = 0.0;
  /// Perspective: full angle across the image width (Horizontal) or height
  /// (Vertical), in [kMinFovDegrees, 180). Fisheye: full angle across the
  /// image circle's diameter, in [kMinFovDegrees, 360] (orthographic up to
  /// 180, stereographic below 360).
  double fov_degrees = 90.0;
  FovAxis fov_axis = FovAxis::Horizontal;
  /// Perspective only: when positive, the full angle across the image height, fov_degrees then being the one across
  /// the width (fov_axis ignored): pixels need not be square. 0: from fov_degrees by square pixels.
  double fov_v_degrees = 0.0;
  /// Fisheye: the lens projection. Perspective: Orthographic makes the planar orthographic view (perspective.h);
  /// every other value is the pinhole.
  Lens lens = Lens::Equidistant;

  bool operator==(const ViewParams&) const = default;
};

/// Orthonormal camera basis of a view: forward, image right, image up (see the
/// file comment).
struct ViewBasis {
  Vec3 forward, right, up;
};
ViewBasis view_basis(const ViewParams& view);

/// Direction from yaw and pitch in degrees: yaw about +Y from +Z towards +X,
/// pitch up towards +Y.
Vec3 direction_from_yaw_pitch(double yaw_degrees, double pitch_degrees);

/// One-line metadata form, e.g.
/// "forward=0,0,1;roll=0;fov=90;axis=h;lens=equidistant", and its parser
/// (throws Error naming the bad field). Numbers are written with 17 significant
/// digits: re-read views are identical.
std::string format_view(const ViewParams& view);
ViewParams parse_view(const std::string& text);

}  // namespace envkit
