#include <envkit/convention.h>
#include <envkit/error.h>

#include <cmath>
#include <sstream>

namespace envkit {

namespace {

// Matrix from its columns: the images of +X, +Y, +Z.
Mat3 from_columns(const Vec3& cx, const Vec3& cy, const Vec3& cz) {
  return Mat3(cx.x, cy.x, cz.x, cx.y, cy.y, cz.y, cx.z, cy.z, cz.z);
}

Convention make(const std::string& name, const std::string& description) {
  Convention c;
  c.name = name;
  c.description = description;
  for (Mat3& m : c.frames) m = identity3();
  return c;
}

std::vector<Convention> build_presets() {
  std::vector<Convention> presets;
  presets.push_back(make("envkit", "canonical frame: +Y up, lat-long centre sees +Z, texel centres at (i+0.5)/N"));

  Convention exr = make("openexr", "OpenEXR ImfEnvmap: corner-sampled lat-long and N x 6N cube, +Y up");
  exr.latlong_grid = TexelGrid::Corner;
  exr.cube_grid = TexelGrid::Corner;
  presets.push_back(exr);

  Convention hdrshop = make("hdrshop", "HDRShop/Debevec: angular map and mirror ball centre +Z, vertical cross");
  hdrshop.cube_layout = CubeLayout::VerticalCross;
  presets.push_back(hdrshop);

  Convention angmap = make("angmap-cal", "Debevec's angmap.cal: angular map and mirror ball centre -Z");
  const Mat3 mirror_z(1, 0, 0, 0, 1, 0, 0, 0, -1);
  angmap.frames[static_cast<int>(Kind::AngularMap)] = mirror_z;
  angmap.frames[static_cast<int>(Kind::MirrorBall)] = mirror_z;
  presets.push_back(angmap);

  Convention blender = make("blender", "Blender/Cycles: Z up, equirect centre +X_b, u=1/4 +Y_b; mirror ball as Cycles (centre +Y_b)");
  // Equirect: envkit's formula rotated about the up axis (+Z -> +X, +X -> -Z): Blender's centre sees its +X.
  const Mat3 yaw90 = from_columns(Vec3(0, 0, -1), Vec3(0, 1, 0), Vec3(1, 0, 0));
  for (Mat3& m : blender.frames) m = yaw90;
  // Cycles' mirror ball (mirrorball_to_direction): the centre sees +Y_b, image right -X_b, image up -Z_b. In envkit's
  // world that is centre -Z, right -X, up -Y: the envkit ball reflected through the origin.
  blender.frames[static_cast<int>(Kind::MirrorBall)] = Mat3(-1, 0, 0, 0, -1, 0, 0, 0, -1);
  blender.cube_layout = CubeLayout::HorizontalCross;
  presets.push_back(blender);

  Convention gl = make("gl", "OpenGL/Vulkan/KTX cube faces (GL face table, texel centres at (i+0.5)/N)");
  gl.cube_basis = CubeBasis::GL;
  gl.cube_layout = CubeLayout::VerticalStrip;
  presets.push_back(gl);
  return presets;
}

const std::vector<Convention>& presets() {
  static const std::vector<Convention> all = build_presets();
  return all;
}

}  // namespace

const Convention& convention(const std::string& name) {
  for (const Convention& c : presets())
    if (c.name == name || (name == "exr" && c.name == "openexr") || (name == "debevec" && c.name == "hdrshop") ||
        (name == "cycles" && c.name == "blender") || (name == "opengl" && c.name == "gl") ||
        (name == "canonical" && c.name == "envkit"))
      return c;
  std::string names;
  for (const Convention& c : presets()) names += (names.empty() ? "" : ", ") + c.name;
  throw Error("unknown convention '" + name + "' (expected one of: " + names + ")");
}

std::vector<std::string> convention_names() {
  std::vector<std::string> names;
  for (const Convention& c : presets()) names.push_back(c.name);
  return names;
}

Mat3 rotation_from_euler_degrees(double yaw, double pitch, double roll) {
  const double y = yaw * kPi / 180.0, p = pitch * kPi / 180.0, r = roll * kPi / 180.0;
  const Mat3 ry(std::cos(y), 0, std::sin(y), 0, 1, 0, -std::sin(y), 0, std::cos(y));
  const Mat3 rx(1, 0, 0, 0, std::cos(p), -std::sin(p), 0, std::sin(p), std::cos(p));
  const Mat3 rz(std::cos(r), -std::sin(r), 0, std::sin(r), std::cos(r), 0, 0, 0, 1);
  return compose(ry, compose(rx, rz));
}

Mat3 parse_rotation(const std::string& text) {
  std::vector<double> values;
  std::string item;
  std::istringstream in(text);
  while (std::getline(in, item, ',')) {
    try {
      std::size_t used = 0;
      const double v = std::stod(item, &used);
      if (item.find_first_not_of(" \t", used) != std::string::npos || !std::isfinite(v)) throw std::invalid_argument(item);
      values.push_back(v);
    } catch (const std::exception&) {
      throw Error("rotation '" + text + "': '" + item + "' is not a number");
    }
  }
  if (values.size() == 3) return rotation_from_euler_degrees(values[0], values[1], values[2]);
  if (values.size() != 9)
    throw Error("rotation '" + text + "': expected 3 Euler angles in degrees (yaw,pitch,roll) or 9 matrix entries");
  Mat3 m(values[0], values[1], values[2], values[3], values[4], values[5], values[6], values[7], values[8]);
  Vec3 c0(m[0][0], m[1][0], m[2][0]), c1(m[0][1], m[1][1], m[2][1]);
  const Vec3 c2(m[0][2], m[1][2], m[2][2]);
  const double det = c0 ^ (c1 % c2);
  const double off = std::abs(c0 ^ c1) + std::abs(c0 ^ c2) + std::abs(c1 ^ c2);
  const double len = std::abs(c0.length() - 1) + std::abs(c1.length() - 1) + std::abs(c2.length() - 1);
  if (std::abs(det - 1.0) > 1e-4 || off > 1e-4 || len > 1e-4)
    throw Error("rotation '" + text + "': the matrix is not a rotation (orthonormal with determinant +1)");
  // Gram-Schmidt so accumulated transforms stay exactly orthonormal.
  c0.normalize();
  c1 = (c1 - (c1 ^ c0) * c0).normalized();
  return from_columns(c0, c1, c0 % c1);
}

std::string format_matrix(const Mat3& m) {
  std::ostringstream s;
  s.precision(9);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) s << (i || j ? "," : "") << m[i][j];
  return s.str();
}

}  // namespace envkit
