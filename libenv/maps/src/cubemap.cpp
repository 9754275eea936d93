#include <envkit/core/error.h>
#include <envkit/maps/cubemap.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <map>

namespace envkit {

namespace {

const Vec3 kAxes[6] = {Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1), Vec3(0, 0, -1)};

int face_of_axis(const Vec3& axis) {
  for (int f = 0; f < 6; ++f)
    if ((kAxes[f] ^ axis) > 0.5) return f;
  return 0;
}

// Per-face (right, down) for the strip layouts, see the table in cubemap.h.
void strip_basis(CubeBasis basis, int face, Vec3& right, Vec3& down) {
  static const Vec3 envkit[6][2] = {{Vec3(0, 0, 1), Vec3(0, -1, 0)},  {Vec3(0, 0, -1), Vec3(0, -1, 0)},
                                    {Vec3(1, 0, 0), Vec3(0, 0, -1)},  {Vec3(1, 0, 0), Vec3(0, 0, 1)},
                                    {Vec3(-1, 0, 0), Vec3(0, -1, 0)}, {Vec3(1, 0, 0), Vec3(0, -1, 0)}};
  static const Vec3 gl[6][2] = {{Vec3(0, 0, -1), Vec3(0, -1, 0)}, {Vec3(0, 0, 1), Vec3(0, -1, 0)},
                                {Vec3(1, 0, 0), Vec3(0, 0, 1)},   {Vec3(1, 0, 0), Vec3(0, 0, -1)},
                                {Vec3(1, 0, 0), Vec3(0, -1, 0)},  {Vec3(-1, 0, 0), Vec3(0, -1, 0)}};
  const auto& table = basis == CubeBasis::GL ? gl : envkit;
  right = table[face][0];
  down = table[face][1];
}

// Unfolds the cube around a front face f with up u and image-right r. Each cell of the net gets
// (axis, right, down) so that neighbouring cells agree along their shared edge.
struct NetCell {
  int cx, cy;
  Vec3 axis, right, down;
};

std::array<NetCell, 6> cross_cells(CubeLayout layout, CubeBasis basis) {
  const Vec3 f(0, 0, 1), u(0, 1, 0);
  // Seen from inside a right-handed frame, right = f x u (-X); the GL table is mirrored (+X).
  const Vec3 r = basis == CubeBasis::GL ? Vec3(1, 0, 0) : f % u;
  if (layout == CubeLayout::HorizontalCross) {
    return {{{1, 1, f, r, -u},
             {2, 1, r, -f, -u},
             {3, 1, -f, -r, -u},
             {0, 1, -r, f, -u},
             {1, 0, u, r, f},
             {1, 2, -u, r, -f}}};
  }
  // Vertical cross: the back face continues below the down face, upside down.
  return {
      {{1, 1, f, r, -u}, {2, 1, r, -f, -u}, {1, 3, -f, r, u}, {0, 1, -r, f, -u}, {1, 0, u, r, f}, {1, 2, -u, r, -f}}};
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

}  // namespace

std::string layout_name(CubeLayout layout) {
  switch (layout) {
    case CubeLayout::VerticalStrip:
      return "vstrip";
    case CubeLayout::HorizontalStrip:
      return "hstrip";
    case CubeLayout::HorizontalCross:
      return "hcross";
    case CubeLayout::VerticalCross:
      return "vcross";
  }
  return "vstrip";
}

CubeLayout parse_layout(const std::string& name) {
  const std::string n = lower(name);
  if (n == "vstrip" || n == "vertical-strip" || n == "openexr" || n == "exr" || n == "sixfiles" || n == "faces")
    return CubeLayout::VerticalStrip;
  if (n == "hstrip" || n == "horizontal-strip" || n == "strip") return CubeLayout::HorizontalStrip;
  if (n == "hcross" || n == "horizontal-cross" || n == "cross") return CubeLayout::HorizontalCross;
  if (n == "vcross" || n == "vertical-cross") return CubeLayout::VerticalCross;
  throw Error("unknown cube layout '" + name + "' (expected vstrip, hstrip, hcross, vcross or faces)");
}

void layout_size(CubeLayout layout, int n, int& width, int& height) {
  switch (layout) {
    case CubeLayout::VerticalStrip:
      width = n;
      height = 6 * n;
      return;
    case CubeLayout::HorizontalStrip:
      width = 6 * n;
      height = n;
      return;
    case CubeLayout::HorizontalCross:
      width = 4 * n;
      height = 3 * n;
      return;
    case CubeLayout::VerticalCross:
      width = 3 * n;
      height = 4 * n;
      return;
  }
}

int face_size_for(CubeLayout layout, int width, int height) {
  int w1 = 0, h1 = 0;
  layout_size(layout, 1, w1, h1);
  if (width <= 0 || height <= 0 || width % w1 != 0 || height % h1 != 0) return 0;
  const int n = width / w1;
  return height / h1 == n ? n : 0;
}

CubeMap::CubeMap(int face_size, CubeLayout layout, CubeBasis basis, TexelGrid grid)
    : Parameterization(0, 0), n_(face_size), layout_(layout), basis_(basis), grid_(grid) {
  if (face_size <= 0) throw Error("cube map face size must be positive");
  if (grid == TexelGrid::CornerRows) throw Error("cube maps are centre- or corner-sampled on both axes");
  layout_size(layout, face_size, width_, height_);
  if (layout == CubeLayout::VerticalStrip || layout == CubeLayout::HorizontalStrip) {
    for (int f = 0; f < 6; ++f) {
      CubeFace& cf = faces_[f];
      cf.face = f;
      cf.axis = kAxes[f];
      strip_basis(basis, f, cf.right, cf.down);
      cf.origin_x = layout == CubeLayout::HorizontalStrip ? f * n_ : 0;
      cf.origin_y = layout == CubeLayout::VerticalStrip ? f * n_ : 0;
    }
  } else {
    for (const NetCell& cell : cross_cells(layout, basis)) {
      const int f = face_of_axis(cell.axis);
      faces_[f] = CubeFace{f, cell.axis, cell.right, cell.down, cell.cx * n_, cell.cy * n_};
    }
  }
  cells_x_ = width_ / n_;
  tap_cell_ = n_;
  slot_face_.fill(-1);
  for (const CubeFace& cf : faces_) {
    slot_face_[(cf.origin_y / n_) * cells_x_ + cf.origin_x / n_] = cf.face;
    max_x_[cf.face] = std::nextafter(static_cast<double>(cf.origin_x + n_), 0.0);
    max_y_[cf.face] = std::nextafter(static_cast<double>(cf.origin_y + n_), 0.0);
  }
}

bool CubeMap::same_grid(const Parameterization& other) const {
  if (!same_kind_and_size(other)) return false;
  const auto& c = static_cast<const CubeMap&>(other);
  return c.n_ == n_ && c.layout_ == layout_ && c.basis_ == basis_ && c.grid_ == grid_;
}

bool CubeMap::has_blank_texels() const {
  return layout_ == CubeLayout::HorizontalCross || layout_ == CubeLayout::VerticalCross;
}

std::vector<std::vector<std::size_t>> CubeMap::twin_texels() const {
  if (grid_ != TexelGrid::Corner || n_ < 2) return {};
  // A corner grid's edge texel centres lie on the cube's edges: the point where a centre's direction meets the cube
  // has coordinates on the grid -1 + 2k / (N - 1), and those integer k name the texel's twins exactly.
  const std::size_t W = std::size_t(width_);
  std::map<std::uint64_t, std::vector<std::size_t>> by_point;
  for (const CubeFace& face : faces_)
    for (int j = 0; j < n_; ++j)
      for (int i = 0; i < n_; ++i) {
        if (i != 0 && i != n_ - 1 && j != 0 && j != n_ - 1) continue;
        const int x = face.origin_x + i, y = face.origin_y + j;
        Vec3 d;
        if (!to_direction(Vec2(x + 0.5, y + 0.5), d)) continue;
        const double m = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
        if (!(m > 0.0)) continue;
        std::uint64_t key = 0;
        for (double p : {d.x / m, d.y / m, d.z / m})
          key = key * std::uint64_t(n_) + std::uint64_t(std::clamp(std::llround((p + 1.0) * 0.5 * (n_ - 1)), 0LL,
                                                                   static_cast<long long>(n_ - 1)));
        by_point[key].push_back(std::size_t(y) * W + std::size_t(x));
      }
  std::vector<std::vector<std::size_t>> groups;
  for (auto& [key, group] : by_point)
    if (group.size() > 1) groups.push_back(std::move(group));
  return groups;
}

std::string CubeMap::describe() const {
  return "cube " + std::to_string(n_) + "^2 faces, " + layout_name(layout_) + " " + std::to_string(width_) + "x" +
         std::to_string(height_) + ", " + (basis_ == CubeBasis::GL ? "GL" : "envkit/OpenEXR") + " face basis, " +
         (grid_ == TexelGrid::Corner ? "corner-sampled (OpenEXR)" : "centre-sampled");
}

int CubeMap::face_at(int i, int j) const {
  if (i < 0 || j < 0 || i >= width_ || j >= height_) return -1;
  return slot_face_[(j / n_) * cells_x_ + i / n_];
}

// A one-texel face (N = 1) has no spacing to divide by in the corner grid; like OpenEXR it looks at the
// face centre, and we let it cover the whole face.
double CubeMap::face_coord(double local) const {
  if (grid_ == TexelGrid::Corner && n_ > 1) return 2.0 * (local - 0.5) / (n_ - 1) - 1.0;
  return 2.0 * local / n_ - 1.0;
}

double CubeMap::local_coord(double a) const {
  if (grid_ == TexelGrid::Corner && n_ > 1) return (a + 1.0) * 0.5 * (n_ - 1) + 0.5;
  return (a + 1.0) * 0.5 * n_;
}

bool CubeMap::to_direction(Vec2 pos, Vec3& dir) const {
  const int f = face_at(static_cast<int>(std::floor(pos.x)), static_cast<int>(std::floor(pos.y)));
  if (f < 0) return false;
  const CubeFace& cf = faces_[f];
  const double a = face_coord(pos.x - cf.origin_x), b = face_coord(pos.y - cf.origin_y);
  dir = (cf.axis + a * cf.right + b * cf.down).normalized();
  return true;
}

Vec2 CubeMap::to_image(const Vec3& d) const {
  // Major axis picks the face; ties go to the first face in order (as OpenEXR does).
  const double ax = std::abs(d.x), ay = std::abs(d.y), az = std::abs(d.z);
  int f;
  if (ax >= ay && ax >= az)
    f = d.x >= 0 ? 0 : 1;
  else if (ay >= az)
    f = d.y >= 0 ? 2 : 3;
  else
    f = d.z >= 0 ? 4 : 5;
  const CubeFace& cf = faces_[f];
  const double major = d ^ cf.axis;
  if (!(major > 0.0)) return Vec2(cf.origin_x + 0.5 * n_, cf.origin_y + 0.5 * n_);  // zero vector
  const double inverse_major = 1.0 / major;
  const double a = std::clamp((d ^ cf.right) * inverse_major, -1.0, 1.0);
  const double b = std::clamp((d ^ cf.down) * inverse_major, -1.0, 1.0);
  // Clamp the final coordinates (not the face-local ones): origin + (n - ulp) can round up onto the next cell.
  const double x0 = cf.origin_x, y0 = cf.origin_y;
  const double x = std::clamp(x0 + local_coord(a), x0, max_x_[f]);
  const double y = std::clamp(y0 + local_coord(b), y0, max_y_[f]);
  return Vec2(x, y);
}

double CubeMap::face_rect_solid_angle(double a0, double b0, double a1, double b1) {
  // Solid angle subtended by [0, a] x [0, b] on the plane at unit distance is atan(a b / sqrt(a^2 + b^2 + 1)).
  auto corner = [](double a, double b) { return std::atan2(a * b, std::sqrt(a * a + b * b + 1.0)); };
  return std::abs(corner(a1, b1) - corner(a0, b1) - corner(a1, b0) + corner(a0, b0));
}

double CubeMap::solid_angle(double x0, double y0, double x1, double y1) const {
  double total = 0.0;
  for (const CubeFace& cf : faces_) {
    // Overlap of the rectangle with this face's square, in face-local pixels.
    const double lx0 = std::max(x0 - cf.origin_x, 0.0), lx1 = std::min(x1 - cf.origin_x, static_cast<double>(n_));
    const double ly0 = std::max(y0 - cf.origin_y, 0.0), ly1 = std::min(y1 - cf.origin_y, static_cast<double>(n_));
    if (lx1 <= lx0 || ly1 <= ly0) continue;
    // Corner grids: half texels that stick out beyond the cube edges hold no extra area.
    const double a0 = std::clamp(face_coord(lx0), -1.0, 1.0), a1 = std::clamp(face_coord(lx1), -1.0, 1.0);
    const double b0 = std::clamp(face_coord(ly0), -1.0, 1.0), b1 = std::clamp(face_coord(ly1), -1.0, 1.0);
    if (a1 > a0 && b1 > b0) total += face_rect_solid_angle(a0, b0, a1, b1);
  }
  return total;
}

// d(omega)/dA on the plane at unit distance is 1 / |v|^3 with v = axis + a right + b down; times (da/dx)^2.
// Every face has the same texel grid, symmetric under the face's mirror lines and its diagonal: the solid angles
// of one eighth of one face give them all (48x fewer evaluations of four atan2).
double CubeMap::texel_solid_angles(std::span<float> out) const {
  const int n = n_;
  const CubeFace& f0 = faces_[0];
  std::vector<double> face(static_cast<std::size_t>(n) * n);
  const int half = (n + 1) / 2;
  tbb::parallel_for(0, half, [&](int j) {
    for (int i = j; i < half; ++i) {
      const double w = texel_solid_angle(f0.origin_x + i, f0.origin_y + j);
      for (const auto& [a, b] : {std::pair{i, j}, std::pair{j, i}})
        for (const int x : {a, n - 1 - a})
          for (const int y : {b, n - 1 - b}) face[static_cast<std::size_t>(y) * n + x] = w;
    }
  });
  double face_total = 0.0;
  for (double w : face) face_total += w;
  std::fill(out.begin(), out.end(), 0.0f);  // the blank cells of a cross
  for (const CubeFace& cf : faces_)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x)
        out[static_cast<std::size_t>(cf.origin_y + y) * width_ + cf.origin_x + x] =
            static_cast<float>(face[static_cast<std::size_t>(y) * n + x]);
  return 6.0 * face_total;
}

double CubeMap::solid_angle_density(Vec2 pos) const {
  const int f = face_at(static_cast<int>(std::floor(pos.x)), static_cast<int>(std::floor(pos.y)));
  if (f < 0) return 0.0;
  const CubeFace& cf = faces_[f];
  const double a = face_coord(pos.x - cf.origin_x), b = face_coord(pos.y - cf.origin_y);
  const double scale = 2.0 / ((grid_ == TexelGrid::Corner && n_ > 1) ? n_ - 1 : n_);
  const double len2 = 1.0 + a * a + b * b;
  return scale * scale / (len2 * std::sqrt(len2));
}

bool CubeMap::resolve_tap(int anchor_i, int anchor_j, int& i, int& j) const {
  const int f = face_at(anchor_i, anchor_j);
  if (f < 0) return clamp_tap(i, j);
  const CubeFace& cf = faces_[f];
  const int li = i - cf.origin_x, lj = j - cf.origin_y;
  if (li >= 0 && li < n_ && lj >= 0 && lj < n_) return true;  // same face
  // Extend the anchor's face plane to the tap's centre and re-project onto the face that sees it.
  const Vec3 dir = cf.axis + face_coord(li + 0.5) * cf.right + face_coord(lj + 0.5) * cf.down;
  const Vec2 p = to_image(dir);
  i = std::min(static_cast<int>(p.x), width_ - 1);
  j = std::min(static_cast<int>(p.y), height_ - 1);
  return true;
}

}  // namespace envkit
