#pragma once
/// @file parameterization.h
/// The common interface of every environment-map parameterization.
///
/// Image coordinates are continuous pixels: texel (i, j) covers [i, i+1) x [j, j+1), its centre is
/// (i + 0.5, j + 0.5), x grows to the right and y grows downwards (row 0 is the top of the file).
/// Directions are expressed in the map's own frame (see convention.h for how a map's frame relates to the
/// canonical envkit world frame, +Y up); they point from the centre towards what is seen.
///
/// Every parameterization keeps its direction->texel map, its texel->direction map and its exact solid
/// angle side by side in one header/source pair (latlong.h, cubemap.h, mirrorball.h, angular.h,
/// octahedral.h, paraboloid.h, healpix.h, perspective.h, fisheye.h, skylatlong.h, skyangular.h).
#include <envkit/core/vec.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace envkit {

enum class Kind {
  LatLong,
  MirrorBall,
  AngularMap,
  CubeMap,
  Octahedral,
  DualParaboloid,
  HEALPix,
  Perspective,
  Fisheye,
  SkyLatLong,
  SkyAngular,
};
/// Number of Kind values (tables indexed by static_cast<int>(Kind)).
inline constexpr int kKindCount = 11;
/// Every kind once, in the order users are shown them (help texts, error messages): the one list of kinds.
inline constexpr std::array<Kind, kKindCount> kAllKinds = {
    Kind::LatLong, Kind::CubeMap,     Kind::MirrorBall, Kind::AngularMap, Kind::Octahedral, Kind::DualParaboloid,
    Kind::HEALPix, Kind::Perspective, Kind::Fisheye,    Kind::SkyLatLong, Kind::SkyAngular};

struct ViewParams;      // view.h
class LatLongMap;       // latlong.h
enum class CubeLayout;  // cubemap.h
enum class CubeBasis;   // cubemap.h

/// "latlong", "mirrorball", "angular", "cube", "octahedral", "paraboloid", "healpix", "perspective", "fisheye",
/// "skylatlong", "skyangular".
std::string kind_name(Kind kind);
/// Inverse of kind_name; also accepts common aliases ("equirect", "lightprobe", "ball", "cubemap",
/// "octa", "dualparaboloid", "hpx", "pinhole", "rectilinear"). Throws Error on unknown names.
Kind parse_kind(const std::string& name);

/// Where texel centres lie relative to the edges of the domain.
enum class TexelGrid {
  /// Texel centres at ((i + 0.5) / W): texels tile the domain exactly (envkit, Blender, GL).
  Centre,
  /// First and last texel centres lie exactly on the domain edges ((i) / (W - 1)): OpenEXR's envmaps.
  /// Edge texels then cover half a texel of the domain.
  Corner,
  /// Lat-long only: columns as Centre (u = (i + 0.5) / W), rows as Corner (v = j / (H - 1), the first and last
  /// rows on the poles). Mitsuba 3's envmap emitter reads its images this way (it pads a copy of column 0 after
  /// the last column and scales v by H - 1).
  CornerRows,
};

/// How a cube map places its six faces in the image (cubemap.h): what code that names, checks or splits a cube file
/// needs to know about its faces.
struct CubeFaceLayout {
  CubeLayout layout;
  CubeBasis basis;
  int face_size = 0;  ///< N: every face is N x N texels
};

class Parameterization {
 public:
  Parameterization(int width, int height) : width_(width), height_(height) {}
  virtual ~Parameterization() = default;

  virtual Kind kind() const = 0;
  /// One line for users, e.g. "latlong 2048x1024, centre-sampled".
  virtual std::string describe() const = 0;
  virtual std::unique_ptr<Parameterization> clone() const = 0;

  int width() const { return width_; }
  int height() const { return height_; }

  /// False for camera views (perspective, most fisheyes): directions they do not see map outside the image, and
  /// maps made from them carry coverage alpha.
  virtual bool covers_sphere() const { return true; }
  /// The view parameters of a camera view (recorded in metadata), nullptr for environment maps.
  virtual const ViewParams* view() const { return nullptr; }
  /// Where the texel centres lie. Lat-long and cube maps take the grid their file calls for; every other
  /// parameterization is centre-sampled.
  virtual TexelGrid grid() const { return TexelGrid::Centre; }
  /// True when some texels may hold no data (outside a disk, the blank cells of a cross): filters then keep a
  /// coverage mask. False when every texel sees part of the sphere.
  virtual bool has_blank_texels() const { return false; }
  /// Groups of texels (indices j * W + i) whose centres are one point of the sphere: the duplicated seam columns of
  /// a corner-sampled lat-long map, the texels a corner-sampled cube shares along its edges and corners. Each
  /// group must hold one value; resampling gives it the solid-angle weighted mean of what its copies received.
  /// Empty when all texel centres are distinct.
  virtual std::vector<std::vector<std::size_t>> twin_texels() const { return {}; }

  /// The face layout of a cube map; nullopt for every other parameterization.
  virtual std::optional<CubeFaceLayout> cube_faces() const { return std::nullopt; }
  /// The lat-long map whose texel (i, j) is this map's texel (i, j) for every texel of this map: a lat-long map
  /// itself, and for a sky lat-long the full-sphere lat-long of twice its height whose upper half it is. Its rows are
  /// bands of constant polar angle and its columns meridians, so loops over this map's texels (rows j < height())
  /// tabulate one value per row and per column instead of one per texel. nullptr for every other parameterization.
  virtual const LatLongMap* latlong_geometry() const { return nullptr; }

  /// Direction (unit length, map frame) seen at continuous image position `pos`.
  /// Returns false where the image holds no data (outside a mirror ball, blank cells of a cross).
  virtual bool to_direction(Vec2 pos, Vec3& dir) const = 0;

  /// Continuous image position that sees `dir` (any non-zero length). For maps that cover the whole sphere
  /// the result lies inside [0, W] x [0, H]; a mirror-ball photograph whose ball is cropped may return a
  /// position outside the image, which callers treat as no coverage.
  virtual Vec2 to_image(const Vec3& dir) const = 0;

  /// Exact solid angle (steradians) of the image rectangle [x0, x1] x [y0, y1] (x0 <= x1, y0 <= y1), counting
  /// only the parts that hold data. Any sub-texel rectangle is allowed; the sum over all texels is 4 pi
  /// (minus whatever a cropped photograph does not see).
  virtual double solid_angle(double x0, double y0, double x1, double y1) const = 0;

  /// Solid angle per unit image area (steradians per square pixel) at pos: the Jacobian of the map, used to weight
  /// sub-samples. 0 where there is no data. The default differentiates solid_angle numerically.
  virtual double solid_angle_density(Vec2 pos) const;

  /// True when `other` lays out exactly the same texels: texel (i, j) of both maps covers the same region of the
  /// map frame's sphere (same kind, size and layout parameters). Resampling between two such maps under the
  /// identity copies the texels. The default says false (a parameterization that cannot tell is never copied).
  virtual bool same_grid(const Parameterization& other) const;

  /// Exact solid angle of texel (i, j); 0 for texels that hold no data.
  double texel_solid_angle(int i, int j) const { return solid_angle(i, j, i + 1.0, j + 1.0); }

  /// texel_solid_angle(i, j) of every texel, rounded to float, into out[j * W + i] (out.size() == W H), and their
  /// sum accumulated in double (independent of the thread count). The default evaluates every texel, rows in
  /// parallel; cube maps evaluate one eighth of one face and copy it by the faces' symmetry.
  virtual double texel_solid_angles(std::span<float> out) const;

  /// A position inside texel (i, j) that holds data: the centre when it does, otherwise (a rim texel holding a
  /// sliver of a disk) some covered point of the texel. False when the texel holds no data at all.
  virtual bool covered_point(int i, int j, Vec2& pos) const;

  /// Filter taps may fall outside the chart (face, image, disk) of the texel being reconstructed.
  /// Given the texel `anchor` the reconstruction is centred on and an integer tap (i, j), rewrite (i, j) into
  /// the texel that sees the same direction: longitude wraps, latitude clamps, cube faces re-project onto the
  /// neighbouring face, octahedral maps fold. Returns false if the tap has no data (the caller then drops it
  /// and renormalises the filter weights).
  virtual bool resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const;

  /// Lets filters skip resolve_tap for the common case: a tap inside the image that lies in the same aligned
  /// tap_cell() x tap_cell() block as its anchor resolves to itself (cube faces: N). 0: every tap inside the image
  /// resolves to itself (lat-long, octahedral, disks, whose blank texels are masked separately); -1: always ask.
  int tap_cell() const { return tap_cell_; }

  /// The texels [x0, x1) x [y0, y1) that resolve to themselves for taps anchored in them (tap_cell()): the aligned
  /// block of an anchor, the whole image when tap_cell() is 0, none when it is -1.
  struct TapBlock {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    bool holds(int i, int j) const { return i >= x0 && i < x1 && j >= y0 && j < y1; }
  };
  /// The TapBlock of anchor texel (anchor_i, anchor_j), inside the image. A loop over many anchors can keep it while
  /// the anchor stays in it, sparing the divisions.
  TapBlock tap_block(int anchor_i, int anchor_j) const {
    if (tap_cell_ == 0) return {0, 0, width_, height_};
    if (tap_cell_ < 0) return {};
    const int x0 = anchor_i / tap_cell_ * tap_cell_, y0 = anchor_j / tap_cell_ * tap_cell_;
    return {x0, y0, std::min(x0 + tap_cell_, width_), std::min(y0 + tap_cell_, height_)};
  }

  /// resolve_tap, without the virtual call for taps that tap_cell() says resolve to themselves.
  bool resolve(int anchor_i, int anchor_j, int& i, int& j) const {
    return tap_block(anchor_i, anchor_j).holds(i, j) || resolve_tap(anchor_i, anchor_j, i, j);
  }

 protected:
  /// Same kind and image size: the part of same_grid() every parameterization shares.
  bool same_kind_and_size(const Parameterization& other) const {
    return other.kind() == kind() && other.width_ == width_ && other.height_ == height_;
  }
  /// Clamp a tap into the image; false only for an empty image.
  bool clamp_tap(int& i, int& j) const;

  int width_;
  int height_;
  int tap_cell_ = 0;
};

}  // namespace envkit
