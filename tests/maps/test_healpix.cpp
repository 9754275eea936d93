// HEALPix parameterization (healpix.h): pixel indices against healpy (an
// independent implementation, run through Debian's /usr/bin/python3), the image
// layout, round trips, exact solid angles, filter taps across base-pixel edges,
// flux conservation into and out of HEALPix, and the tools reading and writing
// it.
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/maps/healpix.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/resample.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "cli_support.h"

namespace fs = std::filesystem;
using namespace envkit;

namespace {

fs::path scratch_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("envkit_test_healpix_" + name + "_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

Vec3 uniform_direction(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double z = 2.0 * u(rng) - 1.0, phi = kTwoPi * u(rng), s = std::sqrt(std::max(0.0, 1.0 - z * z));
  return Vec3(s * std::cos(phi), z, s * std::sin(phi));
}

// Continuous in-cell position of `dir`, its distance (in texels) to the nearest
// texel edge.
double edge_distance(const HealpixMap& map, const Vec3& dir) {
  const Vec2 p = map.to_image(dir);
  const double fx = p.x - std::floor(p.x), fy = p.y - std::floor(p.y);
  return std::min({fx, 1.0 - fx, fy, 1.0 - fy});
}

// healpy's vec2pix for each direction (HEALPix frame) in RING and NESTED,
// through /usr/bin/python3.
void healpy_pixels(int nside, const std::vector<Vec3>& healpix_dirs, std::vector<std::int64_t>& ring,
                   std::vector<std::int64_t>& nest, const fs::path& dir) {
  const fs::path in = dir / "dirs.txt", out = dir / "pix.txt", script = dir / "healpy_pix.py";
  {
    std::ofstream f(in);
    f.precision(17);
    for (const Vec3& d : healpix_dirs) f << d.x << ' ' << d.y << ' ' << d.z << '\n';
  }
  {
    std::ofstream f(script);
    f << "import sys, numpy as np, healpy as hp\n"
         "nside = int(sys.argv[1]); v = np.loadtxt(sys.argv[2]).reshape(-1, "
         "3)\n"
         "r = hp.vec2pix(nside, v[:, 0], v[:, 1], v[:, 2], nest=False)\n"
         "n = hp.vec2pix(nside, v[:, 0], v[:, 1], v[:, 2], nest=True)\n"
         "np.savetxt(sys.argv[3], np.stack([r, n], axis=1), fmt='%d')\n";
  }
  const auto r =
      test::run_command("/usr/bin/python3", {script.string(), std::to_string(nside), in.string(), out.string()}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream f(out);
  std::int64_t a = 0, b = 0;
  while (f >> a >> b) {
    ring.push_back(a);
    nest.push_back(b);
  }
  ASSERT_EQ(ring.size(), healpix_dirs.size());
}

}  // namespace

// 1e5 uniformly random directions: the texel envkit maps each to is the pixel
// healpy's vec2pix names, in both orderings. Margin: directions within 1e-6
// texel of a texel edge (in the continuous image position) are left out; of 1e5
// directions at N_side 64 that is on average 0.4, and the test requires fewer
// than 10.
TEST(Healpix, PixelOfEveryDirectionMatchesHealpyInBothOrderings) {
  const fs::path dir = scratch_dir("healpy");
  for (int nside : {64, 1}) {
    const HealpixMap map(nside);
    std::mt19937_64 rng(20261202 + nside);
    std::vector<Vec3> dirs, hdirs;
    for (int k = 0; k < 100000; ++k) {
      dirs.push_back(uniform_direction(rng));
      hdirs.push_back(HealpixMap::to_healpix_frame(dirs.back()));
    }
    std::vector<std::int64_t> ring, nest;
    healpy_pixels(nside, hdirs, ring, nest, dir);
    ASSERT_EQ(ring.size(), dirs.size());
    int excluded = 0;
    for (std::size_t k = 0; k < dirs.size(); ++k) {
      if (edge_distance(map, dirs[k]) < 1e-6) {
        ++excluded;
        continue;
      }
      const Vec2 p = map.to_image(dirs[k]);
      const int i = int(p.x), j = int(p.y);
      ASSERT_EQ(map.pixel_index(i, j, HealpixOrdering::Ring), ring[k]) << "N_side " << nside << " direction " << k;
      ASSERT_EQ(map.pixel_index(i, j, HealpixOrdering::Nested), nest[k]) << "N_side " << nside << " direction " << k;
    }
    EXPECT_LT(excluded, 10) << "N_side " << nside;
  }
  fs::remove_all(dir);
}

// RING indices of a non-power-of-two N_side (NESTED does not exist there)
// against healpy's ang2pix.
TEST(Healpix, RingIndicesOfANonPowerOfTwoNsideMatchHealpy) {
  const fs::path dir = scratch_dir("healpy_ring");
  const int nside = 48;
  const HealpixMap map(nside);
  std::mt19937_64 rng(7);
  std::vector<Vec3> dirs, hdirs;
  for (int k = 0; k < 20000; ++k) {
    dirs.push_back(uniform_direction(rng));
    hdirs.push_back(HealpixMap::to_healpix_frame(dirs.back()));
  }
  // healpy refuses nest=True for this N_side: its script asks for RING only.
  const fs::path in = dir / "dirs.txt", out = dir / "pix.txt", script = dir / "ring.py";
  {
    std::ofstream f(in);
    f.precision(17);
    for (const Vec3& d : hdirs) f << d.x << ' ' << d.y << ' ' << d.z << '\n';
    std::ofstream s(script);
    s << "import sys, numpy as np, healpy as hp\n"
         "v = np.loadtxt(sys.argv[2]).reshape(-1, 3)\n"
         "np.savetxt(sys.argv[3], hp.vec2pix(int(sys.argv[1]), v[:, 0], v[:, "
         "1], v[:, 2]), fmt='%d')\n";
  }
  const auto r =
      test::run_command("/usr/bin/python3", {script.string(), std::to_string(nside), in.string(), out.string()}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream f(out);
  std::int64_t pix = 0;
  std::size_t k = 0, checked = 0;
  for (; f >> pix; ++k) {
    ASSERT_LT(k, dirs.size());
    if (edge_distance(map, dirs[k]) < 1e-6) continue;
    const Vec2 p = map.to_image(dirs[k]);
    ASSERT_EQ(map.pixel_index(int(p.x), int(p.y), HealpixOrdering::Ring), pix) << "direction " << k;
    ++checked;
  }
  EXPECT_EQ(k, dirs.size());
  EXPECT_GT(checked, dirs.size() - 10);
  EXPECT_THROW(map.pixel_index(0, 0, HealpixOrdering::Nested), Error);
  fs::remove_all(dir);
}

// Texel centres are healpy's pixel centres (pix2vec), for every pixel of N_side
// 8, in both orderings: the layout (which texel holds which pixel) and the
// continuous map agree with the independent implementation.
TEST(Healpix, TexelCentresAreHealpyPixelCentres) {
  const fs::path dir = scratch_dir("centres");
  const int nside = 8;
  const HealpixMap map(nside);
  const fs::path out = dir / "centres.txt", script = dir / "centres.py";
  {
    std::ofstream s(script);
    s << "import sys, numpy as np, healpy as hp\n"
         "n = int(sys.argv[1]); p = np.arange(12 * n * n)\n"
         "r = np.stack(hp.pix2vec(n, p, nest=False), axis=1); q = "
         "np.stack(hp.pix2vec(n, p, nest=True), axis=1)\n"
         "np.savetxt(sys.argv[2], np.concatenate([r, q], axis=1), "
         "fmt='%.17g')\n";
  }
  const auto r = test::run_command("/usr/bin/python3", {script.string(), std::to_string(nside), out.string()}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream f(out);
  std::vector<int> hits(static_cast<std::size_t>(map.width()) * map.height(), 0);
  for (std::int64_t pix = 0; pix < map.pixel_count(); ++pix) {
    Vec3 ring_c, nest_c;
    ASSERT_TRUE(f >> ring_c.x >> ring_c.y >> ring_c.z >> nest_c.x >> nest_c.y >> nest_c.z);
    for (auto [ordering, centre] :
         {std::pair{HealpixOrdering::Ring, ring_c}, std::pair{HealpixOrdering::Nested, nest_c}}) {
      int i = -1, j = -1;
      map.texel_of_pixel(pix, ordering, i, j);
      ASSERT_EQ(map.pixel_index(i, j, ordering), pix);
      Vec3 d;
      ASSERT_TRUE(map.to_direction(Vec2(i + 0.5, j + 0.5), d));
      EXPECT_LT(angle_between(d, HealpixMap::from_healpix_frame(centre)), 1e-12) << "pixel " << pix;
      if (ordering == HealpixOrdering::Ring) ++hits[static_cast<std::size_t>(j) * map.width() + i];
    }
  }
  for (int h : hits) EXPECT_EQ(h, 1);  // every texel is exactly one pixel
  fs::remove_all(dir);
}

// The layout as the header states it: face 0 (north, phi around pi/4) in the
// top-right cell, face 6 (equatorial, phi = pi) in the middle row's second
// cell; the north pole is a cell corner of the top row, +Z (phi = 0) the middle
// of face 4, +X (phi = pi/2) the middle of face 5.
TEST(Healpix, LayoutPutsKnownDirectionsOnKnownTexels) {
  const HealpixMap map(16);
  const auto texel = [&](const Vec3& d) {
    const Vec2 p = map.to_image(d);
    return std::pair{int(p.x), int(p.y)};
  };
  int ix = 0, iy = 0, face = 0;
  auto [zi, zj] = texel(Vec3(0.001, 0.001, 1));
  map.texel_to_xyf(zi, zj, ix, iy, face);
  EXPECT_EQ(face, 4);
  EXPECT_EQ(zi / 16, 3);  // column 3 - 4 % 4
  EXPECT_EQ(zj / 16, 1);
  auto [xi, xj] = texel(Vec3(1, 0.001, 0.001));
  map.texel_to_xyf(xi, xj, ix, iy, face);
  EXPECT_EQ(face, 5);
  EXPECT_EQ(xi / 16, 2);
  // Near the north pole, towards phi = pi/4 (between +Z and +X): face 0, the
  // top-right corner of its cell.
  auto [ni, nj] = texel(Vec3(1e-3, 1, 1e-3));
  map.texel_to_xyf(ni, nj, ix, iy, face);
  EXPECT_EQ(face, 0);
  EXPECT_EQ(ix, 15);
  EXPECT_EQ(iy, 15);
  EXPECT_EQ(ni, 3 * 16 + 15);
  EXPECT_EQ(nj, 0);
  // South pole: faces 8-11, the in-face origin (ix = iy = 0) at the bottom-left
  // of a bottom-row cell.
  auto [si, sj] = texel(Vec3(1e-3, -1, 1e-3));
  map.texel_to_xyf(si, sj, ix, iy, face);
  EXPECT_EQ(face, 8);
  EXPECT_EQ(ix, 0);
  EXPECT_EQ(iy, 0);
  EXPECT_EQ(sj, 3 * 16 - 1);
}

TEST(Healpix, RoundTripsWithin1e6Radians) {
  for (int nside : {1, 5, 256, 8192}) {
    const HealpixMap map(nside);
    std::mt19937_64 rng(nside);
    double worst = 0.0;
    for (int k = 0; k < 20000; ++k) {
      const Vec3 d = uniform_direction(rng);
      Vec3 back;
      ASSERT_TRUE(map.to_direction(map.to_image(d), back));
      worst = std::max(worst, angle_between(d, back));
    }
    EXPECT_LT(worst, 1e-6) << "N_side " << nside;
    // Image -> direction -> image, away from the cell edges where positions on
    // both sides see one direction.
    std::uniform_real_distribution<double> ux(0.0, map.width()), uy(0.0, map.height());
    double worst_pos = 0.0;
    for (int k = 0; k < 20000; ++k) {
      const Vec2 p(ux(rng), uy(rng));
      const double lx = std::fmod(p.x, nside), ly = std::fmod(p.y, nside);
      if (std::min({lx, ly, nside - lx, nside - ly}) < 1e-3) continue;
      Vec3 d;
      ASSERT_TRUE(map.to_direction(p, d));
      worst_pos = std::max(worst_pos, (map.to_image(d) - p).length());
    }
    EXPECT_LT(worst_pos, 1e-5 * std::max(1, nside / 256)) << "N_side " << nside;
  }
}

// Solid angles: every texel 4 pi / (12 N^2), the sum 4 pi; sub-rectangles are
// exact because the map is equal-area in its face coordinates, which uniform
// random directions check (binomial, 5 sigma).
TEST(Healpix, SolidAnglesAreExactForTexelsAndSubRectangles) {
  const HealpixMap map(32);
  const SolidAngleTable omega(map);
  EXPECT_NEAR(omega.total(), kFourPi, 1e-6 * kFourPi);
  double sum = 0.0;
  for (int j = 0; j < map.height(); ++j)
    for (int i = 0; i < map.width(); ++i) {
      ASSERT_DOUBLE_EQ(map.texel_solid_angle(i, j), kFourPi / (12.0 * 32 * 32));
      sum += map.texel_solid_angle(i, j);
    }
  EXPECT_NEAR(sum, kFourPi, 1e-12 * kFourPi);
  struct Rect {
    double x0, y0, x1, y1;
  };
  // A north face's lower-left quarter, a thin strip across the equatorial row,
  // a rectangle across four cells.
  const Rect rects[] = {{96, 0, 112, 16}, {3.3, 32.0, 120.7, 35.5}, {20.25, 20.5, 44.75, 40.125}};
  std::mt19937_64 rng(99);
  const int samples = 400000;
  std::vector<int> inside(std::size(rects), 0);
  for (int k = 0; k < samples; ++k) {
    const Vec2 p = map.to_image(uniform_direction(rng));
    for (std::size_t r = 0; r < std::size(rects); ++r)
      inside[r] += p.x >= rects[r].x0 && p.x < rects[r].x1 && p.y >= rects[r].y0 && p.y < rects[r].y1;
  }
  for (std::size_t r = 0; r < std::size(rects); ++r) {
    const double f = map.solid_angle(rects[r].x0, rects[r].y0, rects[r].x1, rects[r].y1) / kFourPi;
    const double sigma = std::sqrt(f * (1 - f) / samples);
    EXPECT_NEAR(double(inside[r]) / samples, f, 5 * sigma) << "rectangle " << r;
  }
  EXPECT_EQ(map.solid_angle(-5, -5, 0, 10), 0.0);
}

// Filter taps beyond a base pixel's edge land on a texel adjacent (in
// direction) to the anchor, on every edge of every face; taps inside the
// anchor's cell stay where they are.
TEST(Healpix, TapsAcrossBasePixelEdgesLandOnNeighbouringTexels) {
  const int n = 8;
  const HealpixMap map(n);
  const double pixel = std::sqrt(map.pixel_solid_angle());
  for (int face = 0; face < 12; ++face)
    for (int k = 0; k < n; ++k)
      for (auto [ix, iy, dx, dy] :
           {std::tuple{0, k, 0, 1}, std::tuple{n - 1, k, 0, -1}, std::tuple{k, 0, -1, 0}, std::tuple{k, n - 1, 1, 0}}) {
        int ai = 0, aj = 0;
        map.xyf_to_texel(ix, iy, face, ai, aj);
        int i = ai + dx, j = aj + dy;
        ASSERT_TRUE(map.resolve(ai, aj, i, j));
        Vec3 a, t;
        map.to_direction(Vec2(ai + 0.5, aj + 0.5), a);
        map.to_direction(Vec2(i + 0.5, j + 0.5), t);
        EXPECT_LT(angle_between(a, t), 2.6 * pixel) << "face " << face << " texel " << ai << "," << aj;
        EXPECT_GT(angle_between(a, t), 0.2 * pixel) << "face " << face << " texel " << ai << "," << aj;
      }
  int i = 13, j = 3;
  ASSERT_TRUE(map.resolve(12, 2, i, j));
  EXPECT_EQ(i, 13);
  EXPECT_EQ(j, 3);
}

// A sun in one texel of a fine lat-long (1e6 over a 1e-3 sky): its flux
// survives the area filter into HEALPix and back out of it within 0.1%.
TEST(Healpix, AreaFilterConservesTheFluxOfASubTexelSun) {
  const LatLongMap fine(512, 256);
  Image src(512, 256, 3);
  for (float& v : src.pixels) v = 1e-3f;
  for (int c = 0; c < 3; ++c) src.at(301, 77, c) = 1e6f;
  const auto p0 = total_power(src, fine);
  const HealpixMap hpx(8);
  const Mat3 id = identity3();
  const Image mid = resample({src, fine, id}, hpx, id);
  const auto p1 = total_power(mid, hpx);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(p1[c], p0[c], 1e-3 * p0[c]);
  // Out of HEALPix: a sun in one HEALPix texel (N_side 64), into a coarse
  // lat-long and a fine one.
  const HealpixMap fine_hpx(64);
  Image hot(fine_hpx.width(), fine_hpx.height(), 3);
  for (float& v : hot.pixels) v = 1e-3f;
  for (int c = 0; c < 3; ++c) hot.at(100, 77, c) = 1e6f;
  const auto q0 = total_power(hot, fine_hpx);
  for (const LatLongMap& out : {LatLongMap(32, 16), LatLongMap(1024, 512)}) {
    const Image back = resample({hot, fine_hpx, id}, out, id);
    const auto q1 = total_power(back, out);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(q1[c], q0[c], 1e-3 * q0[c]) << out.describe();
  }
}

// Every filter converts a smooth environment into HEALPix and back; bilinear
// and bicubic read across base-pixel edges (resolve_tap), so a seam would show
// up as a texel far from the analytic value.
TEST(Healpix, EveryFilterConvertsBothWays) {
  const auto env = [](const Vec3& d) { return 1.0 + 0.5 * d.x + 0.3 * d.y * d.y + 0.2 * d.z; };
  const LatLongMap ll(256, 128);
  Image src(ll.width(), ll.height(), 1);
  for (int j = 0; j < ll.height(); ++j)
    for (int i = 0; i < ll.width(); ++i) {
      Vec3 d;
      ll.to_direction(Vec2(i + 0.5, j + 0.5), d);
      src.at(i, j, 0) = float(env(d));
    }
  const HealpixMap hpx(40);
  const Mat3 id = identity3();
  for (Filter f : {Filter::Nearest, Filter::Bilinear, Filter::Bicubic, Filter::Area}) {
    ResampleOptions opt;
    opt.filter = f;
    const Image mid = resample({src, ll, id}, hpx, id, opt);
    double worst = 0.0;
    for (int j = 0; j < hpx.height(); ++j)
      for (int i = 0; i < hpx.width(); ++i) {
        Vec3 d;
        hpx.to_direction(Vec2(i + 0.5, j + 0.5), d);
        worst = std::max(worst, std::abs(mid.at(i, j, 0) - env(d)) / env(d));
      }
    EXPECT_LT(worst, f == Filter::Nearest ? 0.02 : 0.004) << "into HEALPix with " << filter_name(f);
    const Image back = resample({mid, hpx, id}, ll, id, opt);
    double worst_back = 0.0;
    for (int j = 0; j < ll.height(); ++j)
      for (int i = 0; i < ll.width(); ++i) {
        Vec3 d;
        ll.to_direction(Vec2(i + 0.5, j + 0.5), d);
        worst_back = std::max(worst_back, std::abs(back.at(i, j, 0) - env(d)) / env(d));
      }
    EXPECT_LT(worst_back, f == Filter::Nearest ? 0.03 : 0.006) << "out of HEALPix with " << filter_name(f);
  }
}

TEST(Healpix, FactoryAndNamesKnowHealpix) {
  EXPECT_EQ(parse_kind("healpix"), Kind::HEALPix);
  EXPECT_EQ(parse_kind("HPX"), Kind::HEALPix);
  EXPECT_EQ(kind_name(Kind::HEALPix), "healpix");
  const auto p = make_parameterization(spec_for(Kind::HEALPix, 16, convention("envkit")));
  EXPECT_EQ(p->width(), 64);
  EXPECT_EQ(p->height(), 48);
  EXPECT_EQ(p->kind(), Kind::HEALPix);
  ParamSpec bad;
  bad.kind = Kind::HEALPix;
  bad.width = 64;
  bad.height = 47;
  EXPECT_THROW(make_parameterization(bad), Error);
}

// The tools: envconvert writes HEALPix and reads it back (from its metadata),
// envinfo names it, envdiff compares it, envbake bakes tables from it.
TEST(Healpix, ToolsReadAndWriteHealpix) {
  const fs::path dir = scratch_dir("cli");
  const LatLongMap ll(128, 64);
  Image img(128, 64, 3);
  img.channel_names = {"R", "G", "B"};
  for (int j = 0; j < 64; ++j)
    for (int i = 0; i < 128; ++i) {
      Vec3 d;
      ll.to_direction(Vec2(i + 0.5, j + 0.5), d);
      for (int c = 0; c < 3; ++c) img.at(i, j, c) = float(1.0 + 0.5 * d[c]);
    }
  const std::string src = (dir / "src.exr").string(), hpx = (dir / "sky_hpx.exr").string(),
                    back = (dir / "back.exr").string(), tables = (dir / "sky.envtbl").string();
  EnvMap m;
  m.image = img;
  m.param = std::make_unique<LatLongMap>(128, 64);
  save_envmap(src, m);
  auto r = test::run_tool("envconvert", {src, "-o", hpx, "--to", "healpix", "--size", "16", "-q"}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const EnvMap loaded = load_envmap(hpx);
  EXPECT_EQ(loaded.param->kind(), Kind::HEALPix);
  EXPECT_EQ(loaded.image.width, 64);
  EXPECT_EQ(loaded.image.height, 48);
  r = test::run_tool("envinfo", {hpx}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("healpix"), std::string::npos) << r.out;
  r = test::run_tool("envconvert", {hpx, "-o", back, "--to", "latlong", "--size", "64", "-q"}, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::run_tool("envdiff", {src, hpx, "--fail-above", "1e-3"}, dir);
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  r = test::run_tool("envbake", {hpx, "-o", tables, "-q"}, dir);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(tables));
  // A 4:3 image says nothing by itself: --from healpix reads it as HEALPix, a
  // wrong size is refused.
  r = test::run_tool("envconvert", {src, "-o", (dir / "x.exr").string(), "--from", "healpix", "--to", "latlong"}, dir);
  EXPECT_EQ(r.code, 1);
  EXPECT_FALSE(fs::exists(dir / "x.exr"));
  fs::remove_all(dir);
}
