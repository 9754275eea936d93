#include <envkit/core/error.h>
#include <envkit/maps/convention.h>

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

  Convention blender =
      make("blender", "Blender/Cycles: Z up, equirect centre +X_b, u=1/4 +Y_b; mirror ball as Cycles (centre +Y_b)");
  // Equirect: envkit's formula rotated about the up axis (+Z -> +X, +X -> -Z): Blender's centre sees its +X.
  const Mat3 yaw90 = from_columns(Vec3(0, 0, -1), Vec3(0, 1, 0), Vec3(1, 0, 0));
  for (Mat3& m : blender.frames) m = yaw90;
  // Cycles' mirror ball (mirrorball_to_direction): the centre sees +Y_b, image right -X_b, image up -Z_b. In envkit's
  // world that is centre -Z, right -X, up -Y: the envkit ball reflected through the origin.
  blender.frames[static_cast<int>(Kind::MirrorBall)] = Mat3(-1, 0, 0, 0, -1, 0, 0, 0, -1);
  blender.cube_layout = CubeLayout::HorizontalCross;
  presets.push_back(blender);

  // Vulkan (spec table "Cube map face selection") and KTX 2 (faces +X -X +Y -Y +Z -Z, rows top down) use the GL
  // face table as is, and Filament's cmgen mirrors its cube by default so that Filament's right-handed world looks
  // it up unmirrored through that table: all three are aliases of this preset (see convention_aliases()).
  Convention gl = make("gl", "OpenGL/Vulkan/KTX/Filament cube faces (GL face table, texel centres at (i+0.5)/N)");
  gl.cube_basis = CubeBasis::GL;
  gl.cube_layout = CubeLayout::VerticalStrip;
  presets.push_back(gl);

  // three.js (src/renderers/shaders/ShaderChunk): equirectUv gives u = atan(d.z, d.x) / 2 pi + 1/2 and
  // v = asin(d.y) / pi + 1/2 with v = 1 on the image's top row, in a world that is envkit's (right-handed, +Y up):
  // the equirect centre sees +X and u = 3/4 sees +Z, envkit's formula turned about +Y like Blender's. Its
  // envmap_fragment reads a CubeTexture as textureCube(envMap, vec3(flipEnvMap * r.x, r.yz)) with flipEnvMap = -1:
  // GL cube faces looked up with x mirrored.
  Convention three =
      make("threejs", "three.js: equirect centre +X (equirectUv); CubeTexture = GL faces with x mirrored");
  for (Mat3& m : three.frames) m = yaw90;
  const Mat3 mirror_x(-1, 0, 0, 0, 1, 0, 0, 0, 1);
  three.frames[static_cast<int>(Kind::CubeMap)] = mirror_x;
  three.cube_basis = CubeBasis::GL;
  presets.push_back(three);

  // Direct3D's world is left-handed (+X right, +Y up, +Z into the screen); the usual port to a right-handed world
  // negates z. A DDS cube holds the faces +X -X +Y -Y +Z -Z, rows top down, each laid out as the GL table has it
  // (D3D and GL share the face table), looked up with D3D world directions.
  Convention dx =
      make("directx", "Direct3D/DDS cube: GL face table in D3D's left-handed world (z negated), faces +X..-Z");
  dx.frames[static_cast<int>(Kind::CubeMap)] = mirror_z;
  dx.cube_basis = CubeBasis::GL;
  dx.cube_layout = CubeLayout::VerticalStrip;
  presets.push_back(dx);

  // Unity's world is left-handed, +Y up; its glTF importer maps glTF's (envkit's) frame to it by negating x
  // (UnityGLTF SchemaExtensions.CoordinateSpaceConversionScale = (-1, 1, 1)). Skybox/Panoramic reads a lat-long
  // with u = 1/2 - atan2(d.z, d.x) / 2 pi, v = 1 - acos(d.y) / pi (v = 1 on the top row): the centre sees Unity's
  // +X (envkit -X) and u = 3/4 Unity's -Z (envkit -Z), a proper rotation of envkit's lat-long. Cube faces are the
  // D3D/GL table looked up with Unity directions, i.e. with envkit's x negated; "6 Frames Layout" strips hold them
  // in the order +X -X +Y -Y +Z -Z.
  Convention unity =
      make("unity", "Unity: left-handed +Y up (x negated); lat-long centre sees Unity +X; GL faces, 6N x N strip");
  unity.frames[static_cast<int>(Kind::LatLong)] = from_columns(Vec3(0, 0, 1), Vec3(0, 1, 0), Vec3(-1, 0, 0));
  unity.frames[static_cast<int>(Kind::CubeMap)] = mirror_x;
  unity.cube_basis = CubeBasis::GL;
  unity.cube_layout = CubeLayout::HorizontalStrip;
  presets.push_back(unity);

  // Mitsuba 3 (src/emitters/envmap.cpp): direction_to_uv gives u = atan2(d.x, -d.z) / 2 pi, v = acos(d.y) / pi in
  // emitter space, which is its right-handed +Y-up world unless to_world says otherwise: envkit's orientation. Its
  // lookup maps u to (u - 1/2W) W (centre-sampled columns) but v to v (H - 1) (rows on the poles).
  Convention mitsuba = make("mitsuba", "Mitsuba 3 envmap emitter: envkit's lat-long orientation, rows corner-sampled");
  mitsuba.latlong_grid = TexelGrid::CornerRows;
  presets.push_back(mitsuba);

  // pbrt-v4's world is left-handed and its scenes are +Z up. As for RenderMan below, its (x, y, z) is envkit's
  // (x, z, y): up goes to up and the handedness flips. ImageInfiniteLight looks its square image up at
  // EqualAreaSphereToSquare(w) (pbrt/util/math.cpp; u = x / N, v = y / N, row 0 at the top). pbrt-v3 lat-longs,
  // the input of imgtool makeequiarea, have u = atan2(y, x) / 2 pi (wrapped to [0, 1)), v = acos(z) / pi.
  Convention pbrt = make("pbrt", "pbrt-v4: equal-area octahedral (Clarberg), +Z up left-handed = envkit (x, z, y)");
  // envkit's octahedral map frame is (x_o, y_o, z_o) = (Z, X, Y) of pbrt's light frame (octahedral.h).
  pbrt.frames[static_cast<int>(Kind::Octahedral)] = from_columns(Vec3(0, 0, 1), Vec3(0, 1, 0), Vec3(1, 0, 0));
  pbrt.frames[static_cast<int>(Kind::LatLong)] = from_columns(Vec3(0, 0, 1), Vec3(0, 1, 0), Vec3(-1, 0, 0));
  presets.push_back(pbrt);

  // OpenImageIO's texture system (src/libtexture/environment.cpp) reads lat-longs tagged oiio:updirection "z", or
  // untagged, the RenderMan way: left-handed, +Z up, s = atan2(y, x) / 2 pi + 1/2, t = 1/2 - asin(z) / pi. With
  // RenderMan's (x, y, z) = envkit (x, z, y) that is envkit's lat-long turned about +Y (centre +X, s = 3/4 +Z), as
  // three.js and Blender have it. Cubes: the GL face table looked up with RenderMan directions.
  Convention rman =
      make("renderman", "RenderMan/OIIO z-up lat-long (oiio:updirection z): centre +X, left-handed = envkit (x, z, y)");
  rman.frames[static_cast<int>(Kind::LatLong)] = yaw90;
  rman.frames[static_cast<int>(Kind::CubeMap)] = Mat3(1, 0, 0, 0, 0, 1, 0, 1, 0);
  rman.cube_basis = CubeBasis::GL;
  presets.push_back(rman);
  // The sky formats are the upper half of a lat-long (skylatlong.h, skyangular.h): under every convention they
  // take its frame, so a convention's sky maps are the top half of its lat-longs.
  for (Convention& c : presets)
    c.frames[static_cast<int>(Kind::SkyLatLong)] = c.frames[static_cast<int>(Kind::SkyAngular)] =
        c.frames[static_cast<int>(Kind::LatLong)];
  return presets;
}

const std::vector<Convention>& presets() {
  static const std::vector<Convention> all = build_presets();
  return all;
}

}  // namespace

const std::vector<std::pair<std::string, std::string>>& convention_aliases() {
  static const std::vector<std::pair<std::string, std::string>> aliases = {
      {"canonical", "envkit"}, {"exr", "openexr"},     {"debevec", "hdrshop"},  {"cycles", "blender"},
      {"opengl", "gl"},        {"vulkan", "gl"},       {"ktx", "gl"},           {"ktx2", "gl"},
      {"filament", "gl"},      {"cmgen", "gl"},        {"three", "threejs"},    {"three.js", "threejs"},
      {"d3d", "directx"},      {"dds", "directx"},     {"mitsuba3", "mitsuba"}, {"pbrt-v4", "pbrt"},
      {"pbrt4", "pbrt"},       {"prman", "renderman"}, {"oiio-z", "renderman"}};
  return aliases;
}

const Convention& convention(const std::string& name) {
  std::string target = name;
  for (const auto& [alias, preset] : convention_aliases())
    if (alias == name) target = preset;
  for (const Convention& c : presets())
    if (c.name == target) return c;
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
      if (item.find_first_not_of(" \t", used) != std::string::npos || !std::isfinite(v))
        throw std::invalid_argument(item);
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
