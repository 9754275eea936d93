// Geometry of every parameterization: round trips, exact solid angles, known directions per convention.
#include <envkit/core/error.h>
#include <envkit/maps/angular.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/mirrorball.h>
#include <envkit/maps/octahedral.h>
#include <envkit/maps/paraboloid.h>
#include <envkit/maps/param_factory.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

using namespace envkit;

namespace {

struct Case {
  std::string name;
  std::function<std::unique_ptr<Parameterization>()> make;
};

std::vector<Case> all_cases() {
  std::vector<Case> cases;
  for (const auto& size : std::vector<std::pair<int, int>>{{1, 1}, {2, 1}, {3, 3}, {7, 5}, {64, 32}, {4096, 2048}}) {
    const int w = size.first, h = size.second;  // plain variables: clang 14 cannot capture structured bindings
    for (TexelGrid g : {TexelGrid::Centre, TexelGrid::Corner, TexelGrid::CornerRows}) {
      cases.push_back({"latlong" + std::to_string(w) + "x" + std::to_string(h) +
                           (g == TexelGrid::Corner       ? "c"
                            : g == TexelGrid::CornerRows ? "r"
                                                         : ""),
                       [=] { return std::make_unique<LatLongMap>(w, h, g); }});
    }
  }
  for (int n : {1, 2, 3, 17, 256}) {
    for (CubeLayout l : {CubeLayout::VerticalStrip, CubeLayout::HorizontalStrip, CubeLayout::HorizontalCross,
                         CubeLayout::VerticalCross}) {
      for (CubeBasis b : {CubeBasis::Envkit, CubeBasis::GL}) {
        for (TexelGrid g : {TexelGrid::Centre, TexelGrid::Corner}) {
          cases.push_back({"cube" + std::to_string(n) + layout_name(l) + (b == CubeBasis::GL ? "gl" : "") +
                               (g == TexelGrid::Corner ? "c" : ""),
                           [=] { return std::make_unique<CubeMap>(n, l, b, g); }});
        }
      }
    }
  }
  for (int n : {1, 2, 3, 9, 64, 4096}) {
    cases.push_back({"mirrorball" + std::to_string(n), [=] { return std::make_unique<MirrorBallMap>(n, n); }});
    cases.push_back({"angular" + std::to_string(n), [=] { return std::make_unique<AngularMap>(n, n); }});
    cases.push_back({"octahedral" + std::to_string(n), [=] { return std::make_unique<OctahedralMap>(n); }});
    cases.push_back({"paraboloid" + std::to_string(n), [=] { return std::make_unique<DualParaboloidMap>(2 * n, n); }});
  }
  return cases;
}

// Visits texels: all of them for small maps, a strided subset plus all border texels for large ones.
template <typename F>
void for_some_texels(const Parameterization& p, F&& f) {
  const std::size_t count = static_cast<std::size_t>(p.width()) * p.height();
  const int stride = count > 200000 ? 37 : 1;
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i)
      if (stride == 1 || (i + j * 7) % stride == 0 || i == 0 || j == 0 || i == p.width() - 1 || j == p.height() - 1)
        f(i, j);
}

double sum_solid_angles(const Parameterization& p) {
  double sum = 0.0;
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) sum += p.texel_solid_angle(i, j);
  return sum;
}

}  // namespace

TEST(Parameterizations, TexelCentreRoundTripWithin1e6Radians) {
  for (const Case& c : all_cases()) {
    auto p = c.make();
    int covered = 0;
    for_some_texels(*p, [&](int i, int j) {
      Vec3 d;
      if (!p->to_direction(Vec2(i + 0.5, j + 0.5), d)) return;
      ++covered;
      ASSERT_NEAR(d.length(), 1.0, 1e-12) << c.name;
      const Vec2 q = p->to_image(d);
      ASSERT_GE(q.x, 0.0) << c.name;
      ASSERT_LE(q.x, p->width()) << c.name;
      ASSERT_GE(q.y, 0.0) << c.name;
      ASSERT_LE(q.y, p->height()) << c.name;
      Vec3 d2;
      ASSERT_TRUE(p->to_direction(q, d2)) << c.name << " texel " << i << "," << j;
      ASSERT_LT(angle_between(d, d2), 1e-6) << c.name << " texel " << i << "," << j;
    });
    EXPECT_GT(covered, 0) << c.name;
  }
}

TEST(Parameterizations, SolidAnglesSumTo4PiWithin1e6Relative) {
  for (const Case& c : all_cases()) {
    auto p = c.make();
    if (static_cast<double>(p->width()) * p->height() > 5e6) continue;  // the big ones are checked below
    EXPECT_NEAR(sum_solid_angles(*p) / kFourPi, 1.0, 1e-6) << c.name;
  }
}

TEST(Parameterizations, LargeMapsSumTo4Pi) {
  EXPECT_NEAR(sum_solid_angles(LatLongMap(4096, 2048)) / kFourPi, 1.0, 1e-6);
  EXPECT_NEAR(sum_solid_angles(LatLongMap(4096, 2048, TexelGrid::Corner)) / kFourPi, 1.0, 1e-6);
  EXPECT_NEAR(sum_solid_angles(LatLongMap(4096, 2048, TexelGrid::CornerRows)) / kFourPi, 1.0, 1e-6);
  EXPECT_NEAR(sum_solid_angles(OctahedralMap(4096)) / kFourPi, 1.0, 1e-6);
  // One 4096^2 face of a cube holds exactly a sixth of the sphere.
  const CubeMap cube(4096);
  double face = 0.0;
  for (int j = 0; j < 4096; ++j)
    for (int i = 0; i < 4096; ++i) face += cube.texel_solid_angle(i, j);
  EXPECT_NEAR(face / (kFourPi / 6.0), 1.0, 1e-6);
  // Radial maps at 4096: the Green's-theorem integral over the whole image and summed per texel row band.
  for (auto p : std::vector<std::shared_ptr<Parameterization>>{std::make_shared<AngularMap>(4096, 4096),
                                                               std::make_shared<MirrorBallMap>(4096, 4096)}) {
    double sum = 0.0;
    for (int j = 0; j < 4096; j += 64) sum += p->solid_angle(0, j, 4096, j + 64);
    EXPECT_NEAR(sum / kFourPi, 1.0, 1e-6);
  }
}

// The band between two parallels: the lat-long rows' bands add up to the sphere, a texel is 2 pi / W of its row's
// band, and nearby angles keep full precision where cos a - cos b would cancel.
TEST(LatLong, BandHeightIsTheRowsSolidAngle) {
  for (const int H : {1, 2, 7, 512}) {
    const int W = 2 * H + 1;
    const LatLongMap map(W, H);
    double sphere = 0.0;
    for (int j = 0; j < H; ++j) {
      const double a = LatLongMap::polar_angle(double(j) / H), b = LatLongMap::polar_angle(double(j + 1) / H);
      const double band = LatLongMap::band_height(a, b);
      EXPECT_NEAR(band, std::cos(a) - std::cos(b), 1e-15) << H << " row " << j;
      EXPECT_NEAR(map.texel_solid_angle(W / 2, j) / (kTwoPi * band / W), 1.0, 1e-14) << H << " row " << j;
      sphere += kTwoPi * band;
    }
    EXPECT_NEAR(sphere / kFourPi, 1.0, 1e-15) << H;
  }
  // cos a - cos b = (b^2 - a^2) / 2 to 1e-19 relative here; the plain difference of the cosines is 0.
  EXPECT_NEAR(LatLongMap::band_height(1e-9, 2e-9) / 1.5e-18, 1.0, 1e-12);
  EXPECT_EQ(LatLongMap::band_height(0.3, 0.3), 0.0);
}

// The hooks that let fast paths find a map's own geometry without knowing its class.
TEST(Parameterizations, GeometryHooksNameTheirOwnMapsOnly) {
  for (const Case& c : all_cases()) {
    auto p = c.make();
    EXPECT_EQ(p->latlong_geometry() != nullptr, p->kind() == Kind::LatLong) << c.name;
    if (p->latlong_geometry()) EXPECT_EQ(static_cast<const void*>(p->latlong_geometry()), p.get()) << c.name;
    const std::optional<CubeFaceLayout> faces = p->cube_faces();
    ASSERT_EQ(faces.has_value(), p->kind() == Kind::CubeMap) << c.name;
    if (faces) {
      const auto& cube = static_cast<const CubeMap&>(*p);
      EXPECT_EQ(faces->layout, cube.layout()) << c.name;
      EXPECT_EQ(faces->basis, cube.basis()) << c.name;
      EXPECT_EQ(faces->face_size, cube.face_size()) << c.name;
    }
  }
}

// Every texel's solid angle at once (cube maps by their faces' symmetry): each texel as texel_solid_angle says,
// blank cells 0, and the double sum of them.
TEST(Parameterizations, TexelSolidAnglesAreEachTexelsSolidAngle) {
  for (const Case& c : all_cases()) {
    auto p = c.make();
    const std::size_t count = static_cast<std::size_t>(p->width()) * p->height();
    if (count > 300000) continue;
    std::vector<float> omega(count, -1.0f);
    const double total = p->texel_solid_angles(omega);
    double sum = 0.0;
    for (int j = 0; j < p->height(); ++j)
      for (int i = 0; i < p->width(); ++i) {
        const double expected = p->texel_solid_angle(i, j);
        ASSERT_NEAR(omega[static_cast<std::size_t>(j) * p->width() + i], expected, 1e-6 * expected + 1e-30)
            << c.name << " texel " << i << "," << j;
        sum += expected;
      }
    EXPECT_NEAR(total, sum, 1e-12 * sum) << c.name;
  }
}

// Independent check of each texel's solid angle: split the texel into small cells and add the spherical
// quadrilaterals spanned by the directions at their corners (Van Oosterom-Strackee triangle formula).
TEST(Parameterizations, TexelSolidAngleMatchesSphericalPolygonQuadrature) {
  auto triangle = [](const Vec3& a, const Vec3& b, const Vec3& c) {
    return 2.0 * std::atan2(std::abs(a ^ (b % c)), 1.0 + (a ^ b) + (b ^ c) + (c ^ a));
  };
  std::vector<std::unique_ptr<Parameterization>> maps;
  maps.push_back(std::make_unique<LatLongMap>(16, 8));
  maps.push_back(std::make_unique<LatLongMap>(15, 9, TexelGrid::Corner));
  maps.push_back(std::make_unique<LatLongMap>(14, 9, TexelGrid::CornerRows));
  maps.push_back(std::make_unique<CubeMap>(5));
  maps.push_back(std::make_unique<CubeMap>(5, CubeLayout::HorizontalCross, CubeBasis::GL, TexelGrid::Corner));
  maps.push_back(std::make_unique<OctahedralMap>(8));
  maps.push_back(std::make_unique<AngularMap>(12, 12));
  maps.push_back(std::make_unique<MirrorBallMap>(12, 12));
  maps.push_back(std::make_unique<DualParaboloidMap>(16, 8));
  const int sub = 48;
  for (const auto& p : maps) {
    // Corner-sampled grids: edge texels hang half outside the domain, where directions repeat; check the
    // interior ones here (their edge halves are covered by the 4 pi sums).
    const bool corner = p->describe().find("corner") != std::string::npos;
    for (int j = corner ? 1 : 0; j < p->height() - (corner ? 1 : 0); ++j) {
      for (int i = corner ? 1 : 0; i < p->width() - (corner ? 1 : 0); ++i) {
        if (corner && dynamic_cast<const CubeMap*>(p.get())) {
          const auto* cube = static_cast<const CubeMap*>(p.get());
          const int f = cube->face_at(i, j);
          if (f < 0) continue;
          const int li = i - cube->face(f).origin_x, lj = j - cube->face(f).origin_y;
          if (li == 0 || lj == 0 || li == cube->face_size() - 1 || lj == cube->face_size() - 1) continue;
        }
        const double exact = p->texel_solid_angle(i, j);
        double quad = 0.0;
        bool rim = false;
        for (int b = 0; b < sub; ++b) {
          for (int a = 0; a < sub; ++a) {
            const double x0 = i + double(a) / sub, x1 = i + double(a + 1) / sub;
            const double y0 = j + double(b) / sub, y1 = j + double(b + 1) / sub;
            Vec3 c00, c10, c01, c11, centre;
            // Only cells fully covered count; partially covered rim cells are resolved by subdividing further.
            const double e = 1e-9;  // stay inside the texel so the corners belong to its face/hemisphere
            if (!p->to_direction(Vec2(0.5 * (x0 + x1), 0.5 * (y0 + y1)), centre) ||
                !p->to_direction(Vec2(x0 + e, y0 + e), c00) || !p->to_direction(Vec2(x1 - e, y0 + e), c10) ||
                !p->to_direction(Vec2(x0 + e, y1 - e), c01) || !p->to_direction(Vec2(x1 - e, y1 - e), c11)) {
              quad += p->solid_angle(x0, y0, x1, y1);  // rim cell: trust the exact form on a 1/48 cell
              rim = true;
              continue;
            }
            quad += triangle(c00, c10, c11) + triangle(c00, c11, c01);
          }
        }
        // Texels on a rim, where the radial maps compress without bound, converge more slowly; the mirror ball
        // crowds its whole rim into one direction, so its rim texels are checked by area below instead.
        if (rim && p->kind() == Kind::MirrorBall) continue;
        ASSERT_NEAR(quad, exact, (rim ? 1e-2 : 2e-3) * exact + 1e-12) << p->describe() << " texel " << i << "," << j;
      }
    }
  }
}

// The mirror ball is equal-area (d omega / dA = 4 on the unit disk): every texel, rim texels included, holds
// 4 x its area inside the disk, measured here by counting points of a fine grid.
TEST(Parameterizations, MirrorBallTexelsAreFourTimesTheirAreaInTheDisk) {
  MirrorBallMap ball(12, 12, 6.0, 6.0, 6.0);
  const int fine = 600;
  for (int j = 0; j < 12; ++j) {
    for (int i = 0; i < 12; ++i) {
      int inside = 0;
      for (int b = 0; b < fine; ++b)
        for (int a = 0; a < fine; ++a) {
          const double x = (i + (a + 0.5) / fine - 6.0) / 6.0, y = (j + (b + 0.5) / fine - 6.0) / 6.0;
          inside += x * x + y * y <= 1.0;
        }
      const double area = double(inside) / (fine * fine) / 36.0;  // normalized units: the disk has area pi
      EXPECT_NEAR(ball.texel_solid_angle(i, j), 4.0 * area, 2e-4) << "texel " << i << "," << j;
    }
  }
}

TEST(Parameterizations, SolidAngleIsAdditiveOverSubRectangles) {
  std::vector<std::unique_ptr<Parameterization>> maps;
  maps.push_back(std::make_unique<AngularMap>(10, 10));
  maps.push_back(std::make_unique<MirrorBallMap>(10, 10, 4.3, 5.1, 3.7));
  maps.push_back(std::make_unique<DualParaboloidMap>(20, 10));
  maps.push_back(std::make_unique<CubeMap>(4, CubeLayout::HorizontalCross));
  for (const auto& p : maps) {
    for (double x0 : {0.0, 1.3, 4.5}) {
      for (double y0 : {0.0, 2.2, 4.9}) {
        const double x1 = x0 + 3.7, y1 = y0 + 2.9, xm = x0 + 1.1, ym = y0 + 2.0;
        const double whole = p->solid_angle(x0, y0, x1, y1);
        const double parts = p->solid_angle(x0, y0, xm, ym) + p->solid_angle(xm, y0, x1, ym) +
                             p->solid_angle(x0, ym, xm, y1) + p->solid_angle(xm, ym, x1, y1);
        EXPECT_NEAR(whole, parts, 1e-12 + 1e-12 * whole) << p->describe();
      }
    }
  }
}

// twin_texels() names exactly the texels whose centres are one point of the sphere (the seam columns of a
// corner-sampled lat-long map, the edges and corners of a corner-sampled cube), has_blank_texels() is true wherever a
// texel holds no data, and only lat-long and cube maps report a grid other than Centre. Found here from the texel
// centres alone.
TEST(Parameterizations, TwinAndBlankTexelsAreWhatTheTexelCentresSay) {
  for (const Case& c : all_cases()) {
    const auto p = c.make();
    const int W = p->width(), H = p->height();
    if (std::size_t(W) * std::size_t(H) > 20000) continue;
    if (p->kind() != Kind::LatLong && p->kind() != Kind::CubeMap) EXPECT_EQ(p->grid(), TexelGrid::Centre) << c.name;
    // Texels keyed by their centre's direction, rounded far below the smallest texel here (1e-2 rad) and far above
    // rounding. A lat-long map's pole row is one point too, but each texel keeps its own longitude's part of the
    // cap: its key adds the column's direction on the equator.
    std::map<std::array<long long, 6>, std::vector<std::size_t>> by_point;
    bool blank = false;
    for (int j = 0; j < H; ++j)
      for (int i = 0; i < W; ++i) {
        Vec3 d;
        if (!(p->texel_solid_angle(i, j) > 0.0) || !p->to_direction(Vec2(i + 0.5, j + 0.5), d)) {
          blank = true;
          continue;
        }
        Vec3 column(0.0, 0.0, 0.0);
        if (p->kind() == Kind::LatLong) p->to_direction(Vec2(i + 0.5, 0.5 * H), column);
        const auto key = [](double x) { return std::llround(x * 1e7); };
        d = d.normalized();
        by_point[{key(d.x), key(d.y), key(d.z), key(column.x), key(column.y), key(column.z)}].push_back(
            std::size_t(j) * std::size_t(W) + std::size_t(i));
      }
    std::vector<std::vector<std::size_t>> want;
    for (auto& [key, group] : by_point)
      if (group.size() > 1) want.push_back(group);
    std::vector<std::vector<std::size_t>> got = p->twin_texels();
    for (auto& group : got) std::sort(group.begin(), group.end());
    std::sort(want.begin(), want.end());
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, want) << c.name;
    if (blank) EXPECT_TRUE(p->has_blank_texels()) << c.name;
  }
}

TEST(Parameterizations, PartialMirrorBallCoversOnlyTheVisiblePart) {
  // A ball whose disk is cropped by the image edge: the image holds less than 4 pi, and every covered texel
  // lies inside the disk.
  MirrorBallMap ball(100, 100, 50.0, 30.0, 40.0);
  const double total = sum_solid_angles(ball);
  EXPECT_LT(total, kFourPi);
  EXPECT_GT(total, 0.5 * kFourPi);
  EXPECT_EQ(ball.texel_solid_angle(0, 99), 0.0);
  Vec3 d;
  EXPECT_FALSE(ball.to_direction(Vec2(0.5, 99.5), d));
  EXPECT_TRUE(ball.to_direction(Vec2(50.0, 30.0), d));
  EXPECT_LT(angle_between(d, Vec3(0, 0, 1)), 1e-12);
}

namespace {
Vec3 world_direction(const Parameterization& p, const Convention& c, Vec2 pos) {
  Vec3 d;
  EXPECT_TRUE(p.to_direction(pos, d));
  return apply(c.frame(p.kind()), d);
}
void expect_direction(const Vec3& got, const Vec3& want, const std::string& what, double tol = 1e-9) {
  EXPECT_LT(angle_between(got, want.normalized()), tol)
      << what << ": got (" << got.x << ", " << got.y << ", " << got.z << ")";
}
}  // namespace

TEST(Conventions, EnvkitLatLong) {
  const Convention& c = convention("envkit");
  LatLongMap m(256, 128);
  expect_direction(world_direction(m, c, Vec2(128, 64)), Vec3(0, 0, 1), "centre sees +Z");
  expect_direction(world_direction(m, c, Vec2(64, 64)), Vec3(1, 0, 0), "u=1/4 sees +X");
  expect_direction(world_direction(m, c, Vec2(192, 64)), Vec3(-1, 0, 0), "u=3/4 sees -X");
  expect_direction(world_direction(m, c, Vec2(0, 64)), Vec3(0, 0, -1), "u=0 sees -Z");
  expect_direction(world_direction(m, c, Vec2(10, 0)), Vec3(0, 1, 0), "top edge is +Y");
  // The first row's centre is half a texel below the pole: theta = pi / (2 H).
  Vec3 d = world_direction(m, c, Vec2(10.5, 0.5));
  EXPECT_NEAR(std::acos(d.y), kPi / 256.0, 1e-12);
}

TEST(Conventions, OpenExrLatLongIsCornerSampled) {
  const Convention& c = convention("openexr");
  auto m = make_parameterization(spec_for(Kind::LatLong, 64, c));
  ASSERT_EQ(m->width(), 128);
  // Pixel centres: column 0 and column W-1 both look along -Z, row 0 is exactly the +Y pole, the middle
  // column (x = (W-1)/2) looks along +Z: OpenEXR's LatLongMap::direction.
  expect_direction(world_direction(*m, c, Vec2(0.5, 31.5 + 0.5)), Vec3(0, 0, -1), "column 0", 0.03);
  expect_direction(world_direction(*m, c, Vec2(0.5, 32.0)), Vec3(0, 0, -1), "column 0 at the equator");
  expect_direction(world_direction(*m, c, Vec2(127.5, 32.0)), Vec3(0, 0, -1), "last column duplicates");
  expect_direction(world_direction(*m, c, Vec2(64.0, 32.0)), Vec3(0, 0, 1), "middle sees +Z");
  expect_direction(world_direction(*m, c, Vec2(40.5, 0.5)), Vec3(0, 1, 0), "row 0 is the pole");
  expect_direction(world_direction(*m, c, Vec2(40.5, 63.5)), Vec3(0, -1, 0), "last row is the other pole");
}

TEST(Conventions, OpenExrCubeFacesSeeTheirAxes) {
  const Convention& c = convention("openexr");
  auto m = make_parameterization(spec_for(Kind::CubeMap, 33, c));
  ASSERT_EQ(m->width(), 33);
  ASSERT_EQ(m->height(), 6 * 33);
  const Vec3 axes[6] = {Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1), Vec3(0, 0, -1)};
  for (int f = 0; f < 6; ++f)
    expect_direction(world_direction(*m, c, Vec2(16.5, f * 33 + 16.5)), axes[f], "face " + std::to_string(f));
  // Edge texel centres lie on the cube edges: OpenEXR's +X face, pixel (0, 0) of the face sees (1, 1, -1)
  // (positionInFace (32, 0) -> pos (1, -1) -> dir (1, pos.x, pos.y)).
  expect_direction(world_direction(*m, c, Vec2(0.5, 0.5)), Vec3(1, 1, -1), "+X face corner");
  // +Z face, top-left texel: lx = m - pif.x, ly = m - pif.y with pif = (32, 32) -> pos (1, 1) -> (1, 1, 1).
  expect_direction(world_direction(*m, c, Vec2(0.5, 4 * 33 + 0.5)), Vec3(1, 1, 1), "+Z face corner");
  // -Y face: pif = (lx, ly): top-left is pos (-1, -1) -> (-1, -1, -1).
  expect_direction(world_direction(*m, c, Vec2(0.5, 3 * 33 + 0.5)), Vec3(-1, -1, -1), "-Y face corner");
}

TEST(Conventions, GlCubeFaceTable) {
  const Convention& c = convention("gl");
  auto m = make_parameterization(spec_for(Kind::CubeMap, 64, c));
  // From the GL spec's table: +X face, s = 1, t = 0.5 is (1, 0, -1); +Y face, s = 0.5, t = 1 is (0, 1, 1);
  // +Z face, s = 1, t = 0 is (1, 1, 1).
  const double e = 1e-9;
  expect_direction(world_direction(*m, c, Vec2(64 - e, 32)), Vec3(1, 0, -1), "+X right edge", 1e-6);
  expect_direction(world_direction(*m, c, Vec2(32, 2 * 64 + 64 - e)), Vec3(0, 1, 1), "+Y bottom edge", 1e-6);
  expect_direction(world_direction(*m, c, Vec2(64 - e, 4 * 64 + e)), Vec3(1, 1, 1), "+Z top-right", 1e-6);
  expect_direction(world_direction(*m, c, Vec2(32, 5 * 64 + 32)), Vec3(0, 0, -1), "-Z centre");
}

TEST(Conventions, BlenderEquirectIsZUpCentrePlusX) {
  const Convention& c = convention("blender");
  auto m = make_parameterization(spec_for(Kind::LatLong, 64, c));
  // Blender world (x_b, y_b, z_b) = envkit (x, -z, y).
  auto to_blender = [](const Vec3& d) { return Vec3(d.x, -d.z, d.y); };
  expect_direction(to_blender(world_direction(*m, c, Vec2(64, 32))), Vec3(1, 0, 0), "centre sees +X_b");
  expect_direction(to_blender(world_direction(*m, c, Vec2(32, 32))), Vec3(0, 1, 0), "u=1/4 sees +Y_b");
  expect_direction(to_blender(world_direction(*m, c, Vec2(20, 0))), Vec3(0, 0, 1), "top is +Z_b");
  // Cycles' formula: phi = pi - 2 pi u, theta = pi v_top.
  const double u = 0.3, v = 0.2;
  const double phi = kPi - kTwoPi * u, theta = kPi * v;
  expect_direction(to_blender(world_direction(*m, c, Vec2(u * 128, v * 64))),
                   Vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)),
                   "Cycles equirect formula");
}

TEST(Conventions, BlenderMirrorBallMatchesCycles) {
  const Convention& c = convention("blender");
  auto m = make_parameterization(spec_for(Kind::MirrorBall, 64, c));
  auto to_blender = [](const Vec3& d) { return Vec3(d.x, -d.z, d.y); };
  // Cycles mirrorball_to_direction(u, v): n = (2u-1, -sqrt(1-x^2-z^2), 2v-1), I = (0,1,0), dir = 2 (n.I) n - I,
  // with v = 1 at the top of the image.
  for (auto [u, v] : std::vector<std::pair<double, double>>{{0.5, 0.5}, {0.7, 0.4}, {0.2, 0.7}, {0.5, 0.9}}) {
    const double x = 2 * u - 1, z = 2 * v - 1;
    const Vec3 n(x, -std::sqrt(1 - x * x - z * z), z);
    const Vec3 want = 2.0 * (n ^ Vec3(0, 1, 0)) * n - Vec3(0, 1, 0);
    expect_direction(to_blender(world_direction(*m, c, Vec2(u * 64, (1 - v) * 64))), want, "Cycles mirror ball", 1e-9);
  }
}

TEST(Conventions, DebevecAngularMapCentreAndRim) {
  const Convention& c = convention("hdrshop");
  AngularMap m(101, 101);
  expect_direction(world_direction(m, c, Vec2(50.5, 50.5)), Vec3(0, 0, 1), "centre sees +Z");
  // Half way to the right rim is 90 degrees from the centre: +X (Debevec: u = Dx r).
  expect_direction(world_direction(m, c, Vec2(50.5 + 25.25, 50.5)), Vec3(1, 0, 0), "r = 1/2 right sees +X");
  expect_direction(world_direction(m, c, Vec2(50.5, 50.5 - 25.25)), Vec3(0, 1, 0), "r = 1/2 up sees +Y");
  Vec3 rim = world_direction(m, c, Vec2(101 - 1e-9, 50.5));
  expect_direction(rim, Vec3(0, 0, -1), "rim sees -Z", 1e-6);
  // Debevec's formula for an arbitrary direction.
  const Vec3 d = Vec3(0.3, -0.5, 0.4).normalized();
  const double r = std::acos(d.z) / (kPi * std::hypot(d.x, d.y));
  const Vec2 p = m.to_image(d);
  EXPECT_NEAR((p.x - 50.5) / 50.5, d.x * r, 1e-12);
  EXPECT_NEAR((50.5 - p.y) / 50.5, d.y * r, 1e-12);
  // angmap.cal mirrors the centre to -Z.
  expect_direction(world_direction(m, convention("angmap-cal"), Vec2(50.5, 50.5)), Vec3(0, 0, -1), "angmap.cal");
}

TEST(Conventions, MirrorBallReflectsTowardsTheCamera) {
  MirrorBallMap m(200, 200);
  const Convention& c = convention("hdrshop");
  expect_direction(world_direction(m, c, Vec2(100, 100)), Vec3(0, 0, 1), "centre sees +Z");
  // r = sin(45 deg) to the right: 90 degrees from +Z towards +X.
  expect_direction(world_direction(m, c, Vec2(100 + 100 * std::sqrt(0.5), 100)), Vec3(1, 0, 0), "+X");
  // The whole rim is -Z; to_image(-Z) is the documented rim point to the right of the centre.
  const Vec2 p = m.to_image(Vec3(0, 0, -1));
  EXPECT_NEAR(p.x, 200.0, 1e-6);
  EXPECT_NEAR(p.y, 100.0, 1e-9);
}

TEST(Conventions, OctahedralAndParaboloidFrames) {
  OctahedralMap o(64);
  const Convention& c = convention("envkit");
  expect_direction(world_direction(o, c, Vec2(32, 32)), Vec3(0, 1, 0), "octahedral centre +Y");
  expect_direction(world_direction(o, c, Vec2(1e-9, 1e-9)), Vec3(0, -1, 0), "octahedral corner -Y", 1e-4);
  expect_direction(world_direction(o, c, Vec2(64 - 1e-9, 32)), Vec3(0, 0, 1), "right edge +Z", 1e-6);
  expect_direction(world_direction(o, c, Vec2(32, 64 - 1e-9)), Vec3(1, 0, 0), "bottom edge +X", 1e-6);
  DualParaboloidMap p(128, 64);
  expect_direction(world_direction(p, c, Vec2(32, 32)), Vec3(0, 0, 1), "left centre +Z");
  expect_direction(world_direction(p, c, Vec2(96, 32)), Vec3(0, 0, -1), "right centre -Z");
  expect_direction(world_direction(p, c, Vec2(64 - 1e-9, 32)), Vec3(-1, 0, 0), "seam -X (left)", 1e-6);
  expect_direction(world_direction(p, c, Vec2(64 + 1e-9, 32)), Vec3(-1, 0, 0), "seam -X (right)", 1e-6);
}

// Every fold of a cross is seamless: texels on both sides of a shared edge see neighbouring directions.
TEST(CubeMaps, CrossesAreSeamless) {
  for (CubeLayout l : {CubeLayout::HorizontalCross, CubeLayout::VerticalCross})
    for (CubeBasis b : {CubeBasis::Envkit, CubeBasis::GL}) {
      const int n = 16;
      CubeMap m(n, l, b);
      // Each face's border texel: step one texel outwards through resolve_tap and compare directions.
      for (int f = 0; f < 6; ++f) {
        const CubeFace& cf = m.face(f);
        for (int k = 0; k < n; ++k) {
          const int border[4][4] = {{cf.origin_x + k, cf.origin_y, 0, -1},
                                    {cf.origin_x + k, cf.origin_y + n - 1, 0, 1},
                                    {cf.origin_x, cf.origin_y + k, -1, 0},
                                    {cf.origin_x + n - 1, cf.origin_y + k, 1, 0}};
          for (const auto& t : border) {
            int i = t[0] + t[2], j = t[1] + t[3];
            ASSERT_TRUE(m.resolve_tap(t[0], t[1], i, j));
            Vec3 a, c;
            ASSERT_TRUE(m.to_direction(Vec2(t[0] + 0.5, t[1] + 0.5), a));
            ASSERT_TRUE(m.to_direction(Vec2(i + 0.5, j + 0.5), c)) << m.describe() << " tap " << i << "," << j;
            // Neighbours across an edge are about one texel apart (2/n in face units at the edge).
            EXPECT_LT(angle_between(a, c), 2.0 / n) << m.describe() << " face " << f;
            EXPECT_GT(angle_between(a, c), 0.2 / n) << m.describe() << " face " << f;
          }
        }
      }
      // Geometric continuity of the net itself: where two faces touch in the image, the directions agree.
      for (int j = 0; j < m.height(); ++j)
        for (int i = 0; i + 1 < m.width(); ++i) {
          const int fa = m.face_at(i, j), fb = m.face_at(i + 1, j);
          if (fa < 0 || fb < 0 || fa == fb) continue;
          Vec3 a, c;
          m.to_direction(Vec2(i + 1 - 1e-9, j + 0.5), a);
          m.to_direction(Vec2(i + 1 + 1e-9, j + 0.5), c);
          EXPECT_LT(angle_between(a, c), 1e-6) << m.describe() << " at " << i << "," << j;
        }
      for (int j = 0; j + 1 < m.height(); ++j)
        for (int i = 0; i < m.width(); ++i) {
          const int fa = m.face_at(i, j), fb = m.face_at(i, j + 1);
          if (fa < 0 || fb < 0 || fa == fb) continue;
          Vec3 a, c;
          m.to_direction(Vec2(i + 0.5, j + 1 - 1e-9), a);
          m.to_direction(Vec2(i + 0.5, j + 1 + 1e-9), c);
          EXPECT_LT(angle_between(a, c), 1e-6) << m.describe() << " at " << i << "," << j;
        }
    }
}

TEST(CubeMaps, EnvkitCrossHorizonMatchesLatLongOrder) {
  // Middle row of the envkit horizontal cross reads +X +Z -X -Z, the order of a lat-long's horizon.
  CubeMap m(8, CubeLayout::HorizontalCross);
  const Vec3 want[4] = {Vec3(1, 0, 0), Vec3(0, 0, 1), Vec3(-1, 0, 0), Vec3(0, 0, -1)};
  for (int k = 0; k < 4; ++k) {
    Vec3 d;
    ASSERT_TRUE(m.to_direction(Vec2(k * 8 + 4, 12), d));
    expect_direction(d, want[k], "cell " + std::to_string(k));
  }
  Vec3 d;
  EXPECT_FALSE(m.to_direction(Vec2(1, 1), d));  // blank cell
  EXPECT_EQ(m.texel_solid_angle(0, 0), 0.0);
}

TEST(ResolveTap, LatLongWrapsAndClamps) {
  LatLongMap m(16, 8);
  int i = -1, j = 3;
  ASSERT_TRUE(m.resolve_tap(0, 3, i, j));
  EXPECT_EQ(i, 15);
  i = 16;
  j = -1;
  ASSERT_TRUE(m.resolve_tap(15, 0, i, j));
  EXPECT_EQ(i, 0);
  EXPECT_EQ(j, 0);
  LatLongMap corner(17, 9, TexelGrid::Corner);
  i = 17;
  j = 2;  // one past the duplicated column 16 == column 0, so column 1
  ASSERT_TRUE(corner.resolve_tap(16, 2, i, j));
  EXPECT_EQ(i, 1);
  // Corner rows keep the full period of centre-sampled columns: no column is duplicated.
  LatLongMap rows(16, 9, TexelGrid::CornerRows);
  i = 16;
  j = 9;
  ASSERT_TRUE(rows.resolve_tap(15, 8, i, j));
  EXPECT_EQ(i, 0);
  EXPECT_EQ(j, 8);
}

TEST(ResolveTap, OctahedralFoldIsContinuous) {
  const int n = 32;
  OctahedralMap m(n);
  for (int k = 0; k < n; ++k) {
    for (auto [ai, aj, di, dj] :
         std::vector<std::array<int, 4>>{{0, k, -1, 0}, {n - 1, k, 1, 0}, {k, 0, 0, -1}, {k, n - 1, 0, 1}}) {
      int i = ai + di, j = aj + dj;
      ASSERT_TRUE(m.resolve_tap(ai, aj, i, j));
      Vec3 a, b;
      m.to_direction(Vec2(ai + 0.5, aj + 0.5), a);
      m.to_direction(Vec2(i + 0.5, j + 0.5), b);
      EXPECT_LT(angle_between(a, b), 4.0 * std::sqrt(kFourPi) / n) << ai << "," << aj << " -> " << i << "," << j;
    }
  }
}

TEST(ResolveTap, ParaboloidCrossesTheEquator) {
  DualParaboloidMap m(64, 32);
  // The rightmost covered texel of the left disk on its middle row, stepping right, continues into the
  // right disk (both see about -X).
  int ai = 31, aj = 15, i = 33, j = 15;
  ASSERT_TRUE(m.resolve_tap(ai, aj, i, j));
  Vec3 a, b;
  ASSERT_TRUE(m.to_direction(Vec2(ai + 0.5, aj + 0.5), a));
  ASSERT_TRUE(m.to_direction(Vec2(i + 0.5, j + 0.5), b));
  EXPECT_GE(i, 32);
  EXPECT_LT(angle_between(a, b), 0.3);
}

TEST(Rotation, EulerAndMatrixParsing) {
  const Mat3 r = parse_rotation("90,0,0");
  expect_direction(apply(r, Vec3(0, 0, 1)), Vec3(1, 0, 0), "yaw 90 takes +Z to +X");
  const Mat3 p = parse_rotation("0,90,0");
  expect_direction(apply(p, Vec3(0, 0, 1)), Vec3(0, -1, 0), "pitch 90 takes +Z to -Y");
  const Mat3 m = parse_rotation("0,0,1, 0,1,0, -1,0,0");
  expect_direction(apply(m, Vec3(0, 0, 1)), Vec3(1, 0, 0), "matrix");
  EXPECT_THROW(parse_rotation("1,2"), Error);
  EXPECT_THROW(parse_rotation("1,0,0,0,1,0,0,0,-1"), Error);  // a reflection
  EXPECT_THROW(parse_rotation("a,b,c"), Error);
}
