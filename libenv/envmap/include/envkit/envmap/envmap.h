#pragma once
/// @file envmap.h
/// An environment map: an image, the parameterization that lays it out, and the matrix that takes its
/// map-frame directions to the canonical envkit world. Loading detects the parameterization (from envkit's
/// metadata, the OpenEXR envmap attribute, or the aspect ratio) and the convention (an option, envkit metadata, the
/// OpenEXR envmap attribute, then OIIO's oiio:updirection / oiio:sampleborder, see oiio_env_tags.h) and assembles
/// six-file cube maps; saving writes metadata naming the parameterization, convention and filter (and a camera
/// view's envkit:view), OIIO's environment tags where they describe the map, and the OpenEXR envmap attribute
/// where the output is OpenEXR-conformant.
#include <envkit/core/image.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/parameterization.h>
#include <envkit/resample/resample.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace envkit {

struct EnvMap {
  Image image;
  std::unique_ptr<Parameterization> param;
  /// Convention the map was read with or is written for (see convention.h).
  std::string convention = "envkit";
  /// User rotation applied on top of the convention's frame (identity unless rotated).
  Mat3 rotation = identity3();

  /// Map frame -> canonical world: rotation x convention frame.
  Mat3 to_world() const;
  MapRef ref() const { return MapRef{image, *param, to_world()}; }
};

struct LoadOptions {
  std::optional<Kind> kind;          ///< --from; empty = detect
  std::optional<CubeLayout> layout;  ///< cube layout; empty = from metadata or the aspect ratio
  /// The convention the file was written for; nullptr = from metadata, "openexr" for files with the envmap
  /// attribute, else "envkit".
  const Convention* convention = nullptr;
  ReadOptions read;
  std::optional<double> ball_cx, ball_cy, ball_radius;  ///< mirror-ball photographs, pixels
  /// Perspective and fisheye inputs: the view (empty = from the envkit:view metadata, else view.h's defaults).
  std::optional<ViewParams> view;
};

/// How the parameterization was decided, for the "assumed ..." message tools print.
struct Detection {
  Kind kind = Kind::LatLong;
  CubeLayout layout = CubeLayout::VerticalStrip;
  std::string convention = "envkit";
  /// Why the convention was chosen when not from an option or envkit metadata, e.g. "from its oiio:updirection=z".
  std::string convention_reason;
  /// Texel grid of a lat-long or cube when the file's oiio:sampleborder differs from the convention's grid.
  std::optional<TexelGrid> grid;
  std::string reason;    ///< e.g. "from the aspect ratio 2:1"
  bool assumed = false;  ///< true when guessed from the aspect ratio (tools say so)
};

/// Decides the parameterization of an image. `path` is used in error messages. Throws Error when --from
/// contradicts the image's size or when nothing fits.
Detection detect_parameterization(const Image& image, const std::string& path, const LoadOptions& options);

/// Paths of a six-file cube pattern: '%' replaced by +X, -X, +Y, -Y, +Z, -Z (as exrenvmap does).
std::vector<std::string> face_paths(const std::string& pattern);
bool is_face_pattern(const std::string& path);

/// Reads an environment map (one file, or six faces when `path` contains '%').
EnvMap load_envmap(const std::string& path, const LoadOptions& options = {}, Detection* detection = nullptr,
                   ReadReport* report = nullptr);

/// Builds an EnvMap around an image already in memory (detection as for load_envmap).
EnvMap make_envmap(Image image, const std::string& path, const LoadOptions& options, Detection* detection = nullptr);

struct SaveOptions {
  WriteOptions write;
  std::string filter;  ///< recorded as envkit:filter when non-empty
  std::string source;  ///< recorded as envkit:source when non-empty
};

/// Writes `map` to `path` (six faces when `path` contains '%', which needs a cube map in a vertical strip).
/// All files are written atomically and together: on failure no output file appears. Returns the values a half
/// output clamped, over every file (clamp_report.h).
ClampReport save_envmap(const std::string& path, const EnvMap& map, const SaveOptions& options = {});

}  // namespace envkit
