// Convention presets against their peers' own formulas: known directions land
// where the peer reads them.
#include <envkit/core/error.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/param_factory.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

using namespace envkit;

namespace {

Vec3 random_direction(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double z = 2 * u(rng) - 1, phi = kTwoPi * u(rng), s = std::sqrt(1 - z * z);
  return Vec3(s * std::cos(phi), s * std::sin(phi), z);
}

// The OpenGL cube-map face selection (OpenGL 4.6 core profile, table 8.19
// "Selection of cube map images"): the major axis picks the face, (sc, tc) then
// give s = (sc / |ma| + 1) / 2, t = (tc / |ma| + 1) / 2, t growing downwards in
// the face image. Faces numbered +X -X +Y -Y +Z -Z.
void gl_cube_lookup(const Vec3& r, int& face, double& s, double& t) {
  const double ax = std::abs(r.x), ay = std::abs(r.y), az = std::abs(r.z);
  double sc, tc, ma;
  if (ax >= ay && ax >= az) {
    face = r.x > 0 ? 0 : 1;
    sc = r.x > 0 ? -r.z : r.z;
    tc = -r.y;
    ma = ax;
  } else if (ay >= az) {
    face = r.y > 0 ? 2 : 3;
    sc = r.x;
    tc = r.y > 0 ? r.z : -r.z;
    ma = ay;
  } else {
    face = r.z > 0 ? 4 : 5;
    sc = r.z > 0 ? r.x : -r.x;
    tc = -r.y;
    ma = az;
  }
  s = 0.5 * (sc / ma + 1);
  t = 0.5 * (tc / ma + 1);
}

}  // namespace

// three.js equirect maps (ShaderChunk common.glsl.js, equirectUv): u =
// atan(d.z, d.x) / (2 pi) + 0.5, v = asin(d.y) / pi + 0.5, v = 1 at the top row
// of the image. A lat-long written with the threejs convention puts every world
// direction where that formula reads it.
TEST(Conventions, ThreejsEquirectMatchesEquirectUv) {
  const Convention& three = convention("threejs");
  EXPECT_EQ(&convention("three.js"), &three);
  const LatLongMap ll(512, 256);
  const Mat3 world_to_map = transposed(three.frame(Kind::LatLong));
  std::mt19937_64 rng(11);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 d = random_direction(rng);
    const double u = std::atan2(d.z, d.x) / kTwoPi + 0.5, v = std::asin(d.y) / kPi + 0.5;
    if (u < 1e-6 || u > 1 - 1e-6) continue;  // the seam: x = 0 and x = W are one column
    const Vec2 p = ll.to_image(apply(world_to_map, d));
    ASSERT_NEAR(p.x, u * 512, 1e-8) << d;
    ASSERT_NEAR(p.y, (1 - v) * 256, 1e-8) << d;
  }
  // Known directions: the image centre sees +X, three quarters across +Z, the
  // top row +Y.
  Vec3 d;
  ll.to_direction(Vec2(256, 128), d);
  EXPECT_LT(angle_between(apply(three.frame(Kind::LatLong), d), Vec3(1, 0, 0)), 1e-12);
  ll.to_direction(Vec2(384, 128), d);
  EXPECT_LT(angle_between(apply(three.frame(Kind::LatLong), d), Vec3(0, 0, 1)), 1e-12);
}

// three.js CubeTexture (envmap_fragment): textureCube(envMap, vec3(flipEnvMap *
// r.x, r.yz)) with flipEnvMap = -1: the world direction r is looked up in the
// GL cube at (-r.x, r.y, r.z). A cube written with the threejs convention has
// r's radiance exactly there.
TEST(Conventions, ThreejsCubeTextureMatchesFlippedGlLookup) {
  const Convention& three = convention("threejs");
  const int n = 64;
  const auto cube = make_parameterization(spec_for(Kind::CubeMap, n, three));
  const auto* c = dynamic_cast<const CubeMap*>(cube.get());
  ASSERT_NE(c, nullptr);
  const Mat3 world_to_map = transposed(three.frame(Kind::CubeMap));
  std::mt19937_64 rng(12);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 r = random_direction(rng);
    int face = 0;
    double s = 0, t = 0;
    gl_cube_lookup(Vec3(-r.x, r.y, r.z), face, s, t);
    const Vec2 p = cube->to_image(apply(world_to_map, r));
    const CubeFace& f = c->face(face);
    ASSERT_EQ(c->face_at(int(p.x), int(p.y)), c->face_at(f.origin_x, f.origin_y)) << r;
    ASSERT_NEAR(p.x - f.origin_x, s * n, 1e-8) << r;
    ASSERT_NEAR(p.y - f.origin_y, t * n, 1e-8) << r;
  }
}

// "gl" stays what the KTX2/DDS writers rely on: the GL face table unmirrored,
// identity frames, centre-sampled.
TEST(Conventions, GlIsTheUnmirroredGlFaceTable) {
  const Convention& gl = convention("gl");
  EXPECT_EQ(gl.cube_basis, CubeBasis::GL);
  EXPECT_EQ(gl.cube_grid, TexelGrid::Centre);
  for (int k = 0; k < kKindCount; ++k) EXPECT_TRUE(is_identity(gl.frames[k]));
  const int n = 32;
  const CubeMap cube(n, CubeLayout::VerticalStrip, CubeBasis::GL);
  std::mt19937_64 rng(13);
  for (int k = 0; k < 2000; ++k) {
    const Vec3 r = random_direction(rng);
    int face = 0;
    double s = 0, t = 0;
    gl_cube_lookup(r, face, s, t);
    const Vec2 p = cube.to_image(r);
    ASSERT_NEAR(p.x, s * n, 1e-8);
    ASSERT_NEAR(p.y - face * n, t * n, 1e-8);
  }
}

namespace {

// Faces as the Vulkan specification tabulates them ("Cube Map Face Selection",
// table "Cube map face selection"; KTX 2 stores the layers in this order, rows
// top down): the major axis picks the layer, then s = (sc / |rc| + 1) / 2 and
// t = (tc / |rc| + 1) / 2 with (sc, tc) the dot products of r with the two
// vectors below. Kept as data, independent of gl_cube_lookup's branches.
struct FaceRow {
  Vec3 axis, sc, tc;
};
const FaceRow kVulkanFaces[6] = {
    {Vec3(1, 0, 0), Vec3(0, 0, -1), Vec3(0, -1, 0)}, {Vec3(-1, 0, 0), Vec3(0, 0, 1), Vec3(0, -1, 0)},
    {Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(0, 0, 1)},   {Vec3(0, -1, 0), Vec3(1, 0, 0), Vec3(0, 0, -1)},
    {Vec3(0, 0, 1), Vec3(1, 0, 0), Vec3(0, -1, 0)},  {Vec3(0, 0, -1), Vec3(-1, 0, 0), Vec3(0, -1, 0)},
};

void table_cube_lookup(const FaceRow (&rows)[6], const Vec3& r, int& face, double& s, double& t) {
  face = 0;
  for (int f = 1; f < 6; ++f)
    if ((r ^ rows[f].axis) > (r ^ rows[face].axis)) face = f;
  const double ma = r ^ rows[face].axis;
  s = 0.5 * ((r ^ rows[face].sc) / ma + 1);
  t = 0.5 * ((r ^ rows[face].tc) / ma + 1);
}

// A cube written with `conv` puts the radiance of every world direction e
// where the peer reads it: face and (s, t) of lookup(to_peer(e)).
template <typename Lookup, typename ToPeer>
void expect_cube_reads(const Convention& conv, Lookup lookup, ToPeer to_peer, int seed) {
  const int n = 32;
  const auto param = make_parameterization(spec_for(Kind::CubeMap, n, conv));
  const auto* cube = dynamic_cast<const CubeMap*>(param.get());
  ASSERT_NE(cube, nullptr);
  const Mat3 world_to_map = transposed(conv.frame(Kind::CubeMap));
  std::mt19937_64 rng(seed);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 e = random_direction(rng);
    int face = 0;
    double s = 0, t = 0;
    lookup(to_peer(e), face, s, t);
    const Vec2 p = cube->to_image(apply(world_to_map, e));
    const CubeFace& f = cube->face(face);
    ASSERT_EQ(cube->face_at(int(p.x), int(p.y)), cube->face_at(f.origin_x, f.origin_y)) << conv.name << " " << e;
    ASSERT_NEAR(p.x - f.origin_x, s * n, 1e-8) << conv.name << " " << e;
    ASSERT_NEAR(p.y - f.origin_y, t * n, 1e-8) << conv.name << " " << e;
  }
}

// Horizontal distance on a wrapping lat-long row of width w.
double wrapped_dx(double a, double b, double w) {
  const double d = std::fmod(std::abs(a - b), w);
  return std::min(d, w - d);
}

// The world direction seen at continuous image position (x, y) of a map made
// for `conv`.
Vec3 world_at(const Parameterization& param, const Convention& conv, double x, double y) {
  Vec3 d;
  EXPECT_TRUE(param.to_direction(Vec2(x, y), d));
  return apply(conv.frame(param.kind()), d);
}

}  // namespace

// Peers that are exactly another preset are aliases of it, not copies; every
// preset name is listed and an unknown one is refused in one line that names
// them.
TEST(Conventions, AliasesResolveToTheirPreset) {
  const Convention& gl = convention("gl");
  for (const char* alias : {"opengl", "vulkan", "ktx", "ktx2", "filament", "cmgen"})
    EXPECT_EQ(&convention(alias), &gl) << alias;
  EXPECT_EQ(&convention("d3d"), &convention("directx"));
  EXPECT_EQ(&convention("dds"), &convention("directx"));
  EXPECT_EQ(&convention("mitsuba3"), &convention("mitsuba"));
  EXPECT_EQ(&convention("pbrt-v4"), &convention("pbrt"));
  EXPECT_EQ(&convention("oiio-z"), &convention("renderman"));
  const std::vector<std::string> names = convention_names();
  for (const char* name : {"directx", "unity", "mitsuba", "pbrt", "renderman"})
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
  for (const auto& [alias, preset] : convention_aliases()) {
    EXPECT_EQ(std::find(names.begin(), names.end(), alias), names.end()) << alias;
    EXPECT_NE(std::find(names.begin(), names.end(), preset), names.end()) << preset;
  }
  try {
    convention("vulkan2");
    FAIL() << "no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_NE(what.find("unity"), std::string::npos) << what;
    EXPECT_NE(what.find("pbrt"), std::string::npos) << what;
  }
}

// Vulkan/KTX 2 cubes are the gl preset: world directions land where the Vulkan
// face-selection table reads them, in layer order +X -X +Y -Y +Z -Z.
TEST(Conventions, VulkanCubeMatchesVulkanFaceSelectionTable) {
  expect_cube_reads(
      convention("vulkan"),
      [](const Vec3& r, int& f, double& s, double& t) { table_cube_lookup(kVulkanFaces, r, f, s, t); },
      [](const Vec3& e) { return e; }, 21);
}

// Filament (libs/ibl/include/ibl/Cubemap.h, Cubemap::getDirectionFor): texel
// (x, y) of a face, row 0 at the top, sees cx = 2 x / N - 1, cy = 1 - 2 y / N
// as +X (1, cy, -cx), -X (-1, cy, cx), +Y (cx, 1, -cy), -Y (cx, -1, cy),
// +Z (cx, cy, 1), -Z (-cx, cy, -1), and Filament's shaders look it up with the
// world direction (textureLod(light_iblSpecular, r, lod)). cmgen's default
// --mirror (CubemapUtils::mirrorCubemap) fills texel N from the unmirrored
// cube at (-N.x, N.y, N.z), which CubemapUtils::equirectangularToCubemap
// filled from the equirect at xf = atan2(s.x, s.z) / pi, yf = asin(s.y) 2 / pi
// (u = (xf + 1) / 2, v = (1 - yf) / 2, row 0 at the top). The filament preset
// writes both where that pipeline reads them.
TEST(Conventions, FilamentCubeAndEquirectMatchCmgen) {
  const Convention& fil = convention("filament");
  const int n = 16;
  const auto cube = make_parameterization(spec_for(Kind::CubeMap, n, fil));
  const auto* c = dynamic_cast<const CubeMap*>(cube.get());
  ASSERT_NE(c, nullptr);
  for (int f = 0; f < 6; ++f)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const double cx = 2 * (x + 0.5) / n - 1, cy = 1 - 2 * (y + 0.5) / n;
        const Vec3 dirs[6] = {Vec3(1, cy, -cx), Vec3(-1, cy, cx), Vec3(cx, 1, -cy),
                              Vec3(cx, -1, cy), Vec3(cx, cy, 1),  Vec3(-cx, cy, -1)};
        const Vec3 want = dirs[f].normalized();
        const CubeFace& face = c->face(f);
        const double px = face.origin_x + x + 0.5, py = face.origin_y + y + 0.5;
        ASSERT_LT(angle_between(world_at(*cube, fil, px, py), want), 1e-9) << f << " " << x << "," << y;
        const Vec2 p = cube->to_image(apply(transposed(fil.frame(Kind::CubeMap)), want));
        ASSERT_NEAR(p.x, px, 1e-9);
        ASSERT_NEAR(p.y, py, 1e-9);
      }
  const LatLongMap ll(256, 128, fil.latlong_grid);
  const Mat3 world_to_map = transposed(fil.frame(Kind::LatLong));
  std::mt19937_64 rng(22);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 nrm = random_direction(rng);
    const Vec3 s(-nrm.x, nrm.y, nrm.z);  // the mirror cmgen applies
    const double u = 0.5 * (std::atan2(s.x, s.z) / kPi + 1), v = 0.5 * (1 - std::asin(s.y) * 2 / kPi);
    const Vec2 p = ll.to_image(apply(world_to_map, nrm));
    ASSERT_LT(wrapped_dx(p.x, u * 256, 256), 1e-8) << nrm;
    ASSERT_NEAR(p.y, v * 128, 1e-8) << nrm;
  }
}

// Direct3D: faces D3D10_TEXTURECUBE_FACE_POSITIVE_X = 0 ... NEGATIVE_Z = 5
// (d3d10.h; DDS cube faces are stored in this order), each addressed like the
// OpenGL table (the D3D11.3 functional spec's TextureCube face selection), with
// directions in D3D's left-handed world, ported to a right-handed one by
// negating z (Microsoft Learn, "Coordinate Systems (Direct3D 9)").
TEST(Conventions, DirectXCubeIsTheD3DTableInALeftHandedWorld) {
  const Convention& dx = convention("directx");
  EXPECT_EQ(dx.cube_layout, CubeLayout::VerticalStrip);
  expect_cube_reads(
      dx, gl_cube_lookup, [](const Vec3& e) { return Vec3(e.x, e.y, -e.z); }, 23);
  // Known direction: the world's -Z (what a right-handed camera looks at) is
  // D3D's +Z, the centre of face 4.
  const auto cube = make_parameterization(spec_for(Kind::CubeMap, 8, dx));
  const Vec2 p = cube->to_image(apply(transposed(dx.frame(Kind::CubeMap)), Vec3(0, 0, -1)));
  EXPECT_NEAR(p.x, 4, 1e-12);
  EXPECT_NEAR(p.y, 4 * 8 + 4, 1e-12);
}

// Unity: Skybox/Panoramic (DefaultResourcesExtra/Skybox-Panoramic.shader,
// ToRadialCoords) reads a lat-long at u = 1/2 - atan2(d.z, d.x) / 2 pi,
// v = 1 - acos(d.y) / pi with v = 0 on the bottom row; cubemaps are looked up
// with the same Unity direction through the D3D/GL face table, "6 Frames
// Layout" faces left to right +X -X +Y -Y +Z -Z. Unity directions are envkit's
// with x negated (UnityGLTF SchemaExtensions.CoordinateSpaceConversionScale).
TEST(Conventions, UnityMatchesPanoramicSkyboxAndCubeFaces) {
  const Convention& unity = convention("unity");
  const auto to_unity = [](const Vec3& e) { return Vec3(-e.x, e.y, e.z); };
  EXPECT_EQ(unity.cube_layout, CubeLayout::HorizontalStrip);
  expect_cube_reads(unity, gl_cube_lookup, to_unity, 24);
  const LatLongMap ll(512, 256, unity.latlong_grid);
  const Mat3 world_to_map = transposed(unity.frame(Kind::LatLong));
  std::mt19937_64 rng(25);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 e = random_direction(rng), d = to_unity(e);
    const double u = 0.5 - std::atan2(d.z, d.x) / kTwoPi, v = 1 - std::acos(d.y) / kPi;
    const Vec2 p = ll.to_image(apply(world_to_map, e));
    ASSERT_LT(wrapped_dx(p.x, u * 512, 512), 1e-8) << e;
    ASSERT_NEAR(p.y, (1 - v) * 256, 1e-8) << e;
  }
  // The image centre sees Unity's +X, which is envkit's -X.
  EXPECT_LT(angle_between(world_at(ll, unity, 256, 128), Vec3(-1, 0, 0)), 1e-12);
}

// Mitsuba 3 (src/emitters/envmap.cpp): direction_to_uv gives
// u = atan2(d.x, -d.z) / 2 pi, v = acos(d.y) / pi; eval_spectrum looks texel
// (i, j) up at ((u - 1/2W) mod 1) W = i, v (H - 1) = j; uv_to_direction gives
// (sin phi sin theta, cos theta, -cos phi sin theta), phi = 2 pi u,
// theta = pi v. Emitter space is the world unless to_world says otherwise.
TEST(Conventions, MitsubaMatchesEnvmapEmitter) {
  const Convention& mi = convention("mitsuba");
  const int w = 64, h = 33;
  const LatLongMap ll(w, h, mi.latlong_grid);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      const double u = (i + 0.5) / w, v = double(j) / (h - 1);
      const double phi = kTwoPi * u, theta = kPi * v;
      const Vec3 want(std::sin(phi) * std::sin(theta), std::cos(theta), -std::cos(phi) * std::sin(theta));
      ASSERT_LT(angle_between(world_at(ll, mi, i + 0.5, j + 0.5), want), 1e-9) << i << "," << j;
    }
  const Mat3 world_to_map = transposed(mi.frame(Kind::LatLong));
  std::mt19937_64 rng(26);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 d = random_direction(rng);
    const double u = std::atan2(d.x, -d.z) / kTwoPi, v = std::acos(d.y) / kPi;
    double x = u - 0.5 / w;
    x = (x - std::floor(x)) * w;
    const Vec2 p = ll.to_image(apply(world_to_map, d));
    ASSERT_LT(wrapped_dx(p.x, x + 0.5, w), 1e-8) << d;
    ASSERT_NEAR(p.y, v * (h - 1) + 0.5, 1e-8) << d;
  }
}

namespace {

// pbrt-v4 src/pbrt/util/math.cpp EqualAreaSquareToSphere (Clarberg).
Vec3 pbrt_equal_area_square_to_sphere(double px, double py) {
  const double u = 2 * px - 1, v = 2 * py - 1;
  const double up = std::abs(u), vp = std::abs(v);
  const double signed_distance = 1 - (up + vp);
  const double r = 1 - std::abs(signed_distance);
  const double phi = (r == 0 ? 1 : (vp - up) / r + 1) * kPi / 4;
  const double z = std::copysign(1 - r * r, signed_distance);
  const double cos_phi = std::copysign(std::cos(phi), u), sin_phi = std::copysign(std::sin(phi), v);
  return Vec3(cos_phi * r * std::sqrt(std::max(0.0, 2 - r * r)), sin_phi * r * std::sqrt(std::max(0.0, 2 - r * r)), z);
}

// pbrt-v4 src/pbrt/util/math.cpp WrapEqualAreaSquare.
Vec2 pbrt_wrap_equal_area_square(Vec2 uv) {
  if (uv.x < 0) {
    uv.x = -uv.x;
    uv.y = 1 - uv.y;
  } else if (uv.x > 1) {
    uv.x = 2 - uv.x;
    uv.y = 1 - uv.y;
  }
  if (uv.y < 0) {
    uv.x = 1 - uv.x;
    uv.y = -uv.y;
  } else if (uv.y > 1) {
    uv.x = 1 - uv.x;
    uv.y = 2 - uv.y;
  }
  return uv;
}

// pbrt's light frame (left-handed, +Z up) in envkit's world.
Vec3 envkit_from_pbrt(const Vec3& p) { return Vec3(p.x, p.z, p.y); }

}  // namespace

// pbrt-v4 ImageInfiniteLight (src/pbrt/lights.h, Le): the radiance of light
// direction w is the square image at EqualAreaSphereToSquare(w), u = x / N,
// v = y / N (Image::LookupNearest: pixel (u N, v N), row 0 at the top), so
// texel (i, j) sees EqualAreaSquareToSphere((i + 1/2) / N, (j + 1/2) / N).
// Every texel has the solid angle 4 pi / N^2 (PDF_Li divides the image pdf by
// 4 pi and no Jacobian). Taps beyond an edge fold as WrapEqualAreaSquare says.
TEST(Conventions, PbrtMatchesEqualAreaSquareToSphere) {
  const Convention& pbrt = convention("pbrt");
  const int n = 32;
  const auto oct = make_parameterization(spec_for(Kind::Octahedral, n, pbrt));
  const Mat3 world_to_map = transposed(pbrt.frame(Kind::Octahedral));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const Vec3 want = envkit_from_pbrt(pbrt_equal_area_square_to_sphere((i + 0.5) / n, (j + 0.5) / n));
      ASSERT_LT(angle_between(world_at(*oct, pbrt, i + 0.5, j + 0.5), want), 1e-9) << i << "," << j;
      const Vec2 p = oct->to_image(apply(world_to_map, want));
      ASSERT_NEAR(p.x, i + 0.5, 1e-9);
      ASSERT_NEAR(p.y, j + 0.5, 1e-9);
      ASSERT_NEAR(oct->texel_solid_angle(i, j), kFourPi / (n * n), 1e-15);
    }
  for (int j = -1; j <= n; ++j)
    for (int i = -1; i <= n; ++i) {
      const Vec2 w = pbrt_wrap_equal_area_square(Vec2((i + 0.5) / n, (j + 0.5) / n));
      int ri = i, rj = j;
      ASSERT_TRUE(oct->resolve_tap(std::clamp(i, 0, n - 1), std::clamp(j, 0, n - 1), ri, rj));
      EXPECT_EQ(ri, int(w.x * n)) << i << "," << j;
      EXPECT_EQ(rj, int(w.y * n)) << i << "," << j;
    }
  // Known direction: pbrt's +Z (up) is the image centre, envkit's +Y.
  EXPECT_LT(angle_between(world_at(*oct, pbrt, n / 2.0, n / 2.0), Vec3(0, 1, 0)), 1e-12);
}

// pbrt-v3 lat-longs, the input of pbrt-v4's imgtool makeequiarea
// (src/pbrt/cmd/imgtool.cpp): the equal-area direction dir is read at
// (SphericalPhi(dir) / 2 pi, SphericalTheta(dir) / pi) = (atan2(y, x) wrapped
// to [0, 2 pi), acos(z)) scaled, with Bilerp's texel centres at (i + 1/2) / W.
TEST(Conventions, PbrtLatLongMatchesMakeequiarea) {
  const Convention& pbrt = convention("pbrt");
  const LatLongMap ll(256, 128, pbrt.latlong_grid);
  const Mat3 world_to_map = transposed(pbrt.frame(Kind::LatLong));
  std::mt19937_64 rng(27);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 p = random_direction(rng), e = envkit_from_pbrt(p);
    double phi = std::atan2(p.y, p.x);
    if (phi < 0) phi += kTwoPi;
    const double u = phi / kTwoPi, v = std::acos(p.z) / kPi;
    const Vec2 q = ll.to_image(apply(world_to_map, e));
    ASSERT_LT(wrapped_dx(q.x, u * 256, 256), 1e-8) << p;
    ASSERT_NEAR(q.y, v * 128, 1e-8) << p;
  }
}

// OpenImageIO's texture system (src/libtexture/environment.cpp,
// vector_to_latlong): with y_is_up, s = atan2(-R.x, R.z) / 2 pi + 1/2,
// t = 1/2 - atan2(R.y, hypot(R.z, R.x)) / pi: envkit's own frame. Otherwise
// (RenderMan, +Z up, left-handed) s = atan2(R.y, R.x) / 2 pi + 1/2,
// t = 1/2 - atan2(R.z, hypot(R.x, R.y)) / pi: the renderman preset, with
// RenderMan's (x, y, z) = envkit (x, z, y).
TEST(Conventions, RendermanAndEnvkitMatchOiioVectorToLatlong) {
  const Convention &rman = convention("renderman"), &ek = convention("envkit");
  const LatLongMap ll(256, 128);
  std::mt19937_64 rng(28);
  for (int k = 0; k < 10000; ++k) {
    const Vec3 e = random_direction(rng);
    const Vec3 r(e.x, e.z, e.y);
    const double s = std::atan2(r.y, r.x) / kTwoPi + 0.5, t = 0.5 - std::atan2(r.z, std::hypot(r.x, r.y)) / kPi;
    const Vec2 p = ll.to_image(apply(transposed(rman.frame(Kind::LatLong)), e));
    ASSERT_LT(wrapped_dx(p.x, s * 256, 256), 1e-8) << e;
    ASSERT_NEAR(p.y, t * 128, 1e-8) << e;
    const double sy = std::atan2(-e.x, e.z) / kTwoPi + 0.5, ty = 0.5 - std::atan2(e.y, std::hypot(e.z, e.x)) / kPi;
    const Vec2 q = ll.to_image(apply(transposed(ek.frame(Kind::LatLong)), e));
    ASSERT_LT(wrapped_dx(q.x, sy * 256, 256), 1e-8) << e;
    ASSERT_NEAR(q.y, ty * 128, 1e-8) << e;
  }
}
