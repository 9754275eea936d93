#pragma once
/// @file cubemap.h
/// Cube maps: six square faces of N x N texels arranged in one image by a layout.
///
/// Faces are numbered in OpenEXR's order: 0 +X, 1 -X, 2 +Y, 3 -Y, 4 +Z, 5 -Z.
/// Each placed face has a basis (axis, right, down): the image point with face coordinates (a, b) in
/// [-1, 1]^2 (a grows to the right, b downwards) sees the direction axis + a right + b down.
/// Face coordinates of a face-local image position (lx, ly) in [0, N]:
///   TexelGrid::Centre  a = 2 lx / N - 1                 (texel centres at (i + 0.5) / N: GL, envkit)
///   TexelGrid::Corner  a = 2 (lx - 0.5) / (N - 1) - 1   (edge texel centres lie on the cube edges: OpenEXR)
///
/// Face bases:
///   CubeBasis::Envkit (= OpenEXR's ImfEnvmap faces, right-handed, seen from inside):
///     +X: right +Z, down -Y   -X: right -Z, down -Y   +Y: right +X, down -Z
///     -Y: right +X, down +Z   +Z: right -X, down -Y   -Z: right +X, down -Y
///   CubeBasis::GL (the OpenGL/D3D/KTX cube-map face table; s right, t down):
///     +X: right -Z, down -Y   -X: right +Z, down -Y   +Y: right +X, down +Z
///     -Y: right +X, down -Z   +Z: right +X, down -Y   -Z: right -X, down -Y
/// Layouts:
///   VerticalStrip   N x 6N, faces top to bottom in face order (OpenEXR's CUBE; also six separate files).
///   HorizontalStrip 6N x N, faces left to right in face order.
///   HorizontalCross 4N x 3N and VerticalCross 3N x 4N: the cube unfolded around a front face, seamless across
///     every fold. Envkit basis: front +Z, middle row +X +Z -X -Z (the order of a lat-long's horizon);
///     GL basis: middle row -X +Z +X -Z with each face exactly as the GL table has it. The vertical cross puts
///     the back face below the down face, upside down (HDRShop's layout). Cells outside the cross hold no data.
#include <envkit/maps/parameterization.h>

#include <array>

namespace envkit {

enum class CubeLayout { VerticalStrip, HorizontalStrip, HorizontalCross, VerticalCross };
enum class CubeBasis { Envkit, GL };

/// "vstrip", "hstrip", "hcross", "vcross"; parse accepts also "openexr"/"exr" (vertical strip),
/// "strip", "cross" (horizontal ones), "sixfiles"/"faces" (vertical strip, the in-memory form of six files).
std::string layout_name(CubeLayout layout);
CubeLayout parse_layout(const std::string& name);
/// Image size of a layout for face size N.
void layout_size(CubeLayout layout, int face_size, int& width, int& height);
/// Face size implied by an image size for a layout, or 0 if the size does not fit the layout.
int face_size_for(CubeLayout layout, int width, int height);

/// One face as placed in the image.
struct CubeFace {
  int face = 0;                    ///< 0..5: +X, -X, +Y, -Y, +Z, -Z
  Vec3 axis, right, down;          ///< direction = axis + a right + b down
  int origin_x = 0, origin_y = 0;  ///< top-left texel of the face in the image
};

class CubeMap final : public Parameterization {
 public:
  CubeMap(int face_size, CubeLayout layout = CubeLayout::VerticalStrip, CubeBasis basis = CubeBasis::Envkit,
          TexelGrid grid = TexelGrid::Centre);

  Kind kind() const override { return Kind::CubeMap; }
  std::string describe() const override;
  std::unique_ptr<Parameterization> clone() const override { return std::make_unique<CubeMap>(*this); }
  bool same_grid(const Parameterization& other) const override;

  int face_size() const { return n_; }
  CubeLayout layout() const { return layout_; }
  CubeBasis basis() const { return basis_; }
  TexelGrid grid() const override { return grid_; }
  bool has_blank_texels() const override;
  std::vector<std::vector<std::size_t>> twin_texels() const override;
  std::optional<CubeFaceLayout> cube_faces() const override { return CubeFaceLayout{layout_, basis_, n_}; }
  /// The placed face with face number `face` (0..5).
  const CubeFace& face(int face) const { return faces_[face]; }
  /// Index into face() of the face that holds image texel (i, j), or -1 for blank cells and outside.
  int face_at(int i, int j) const;

  bool to_direction(Vec2 pos, Vec3& dir) const override;
  Vec2 to_image(const Vec3& dir) const override;
  double solid_angle(double x0, double y0, double x1, double y1) const override;
  double solid_angle_density(Vec2 pos) const override;
  double texel_solid_angles(std::span<float> out) const override;
  bool resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const override;

  /// Exact solid angle of the face-coordinate rectangle [a0, a1] x [b0, b1] (within [-1, 1]^2) of any face.
  static double face_rect_solid_angle(double a0, double b0, double a1, double b1);

 private:
  double face_coord(double local) const;  // face-local pixel coordinate -> a (or b)
  double local_coord(double a) const;     // inverse
  int n_;
  CubeLayout layout_;
  CubeBasis basis_;
  TexelGrid grid_;
  std::array<CubeFace, 6> faces_;
  std::array<int, 16> slot_face_;  // face in each N x N cell of the layout (up to 4 x 4 cells), or -1
  int cells_x_ = 1;
  std::array<double, 6> max_x_, max_y_;  // largest positions inside each face
};

}  // namespace envkit
