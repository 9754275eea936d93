// White furnace and mirror tests of envrender's integrator: a sphere in a constant environment L.
// Lambertian albedo rho renders rho L; a mirror of reflectance r renders r L; for every strategy.
#include <envkit/envmap/envmap.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/render/integrator.h>
#include <envkit/render/material.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <envkit/tables/env_tables.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "render_support.h"

using namespace envkit;
using namespace envkit::render;

namespace {

struct ConstantEnvironment {
  EnvMap map;
  std::shared_ptr<const EnvTables> tables;
  std::unique_ptr<EnvironmentLight> light;
  explicit ConstantEnvironment(const Vec3& L) {
    LatLongMap grid(64, 32);
    LoadOptions load;
    load.kind = Kind::LatLong;
    map = make_envmap(probes::rasterize(probes::ConstantProbe(L), grid), "constant", load);
    BakeOptions bake;
    bake.compensated = true;
    tables = std::make_shared<EnvTables>(EnvTables::bake(map, bake));
    light = std::make_unique<EnvironmentLight>(map, tables);
  }
};

struct Case {
  const char* name;
  IntegratorOptions options;
};

std::vector<Case> all_strategies() {
  std::vector<Case> cases;
  auto add = [&](const char* name, Strategy s, SamplingMethod m = SamplingMethod::Hierarchical,
                 Heuristic h = Heuristic::Power, int n = 1, int mm = 1) {
    cases.push_back({name, envkit::test::strategy_options(s, m, h, n, mm)});
  };
  add("bsdf", Strategy::Bsdf);
  add("light-cdf", Strategy::Light, SamplingMethod::Cdf);
  add("light-alias", Strategy::Light, SamplingMethod::Alias);
  add("light-hierarchical", Strategy::Light, SamplingMethod::Hierarchical);
  add("mis-balance", Strategy::Mis, SamplingMethod::Cdf, Heuristic::Balance);
  add("mis-power-2x3", Strategy::Mis, SamplingMethod::Hierarchical, Heuristic::Power, 2, 3);
  add("mis-balance-alias", Strategy::Mis, SamplingMethod::Alias, Heuristic::Balance);
  add("mis-compensated", Strategy::MisCompensated, SamplingMethod::Hierarchical);
  add("product", Strategy::Product);
  add("product-mis", Strategy::ProductMis);
  return cases;
}

/// A unit sphere at the origin seen by a camera whose central window lies wholly on the sphere.
struct FurnaceScene {
  Scene scene;
  Camera camera{Vec3(0, 0, -4), Vec3(0, 0, 0), Vec3(0, 1, 0), 20.0, 12, 12};
  explicit FurnaceScene(std::unique_ptr<Material> material) {
    const int m = scene.add_material("m", std::move(material));
    scene.add_sphere(Vec3(0, 0, 0), 1.0, m);
    scene.commit();
  }
};

/// Checks every pixel of `film` against `expected` (per channel) within `k` sigma (+ a relative 1e-9 for
/// zero-variance estimators) and the image average within 3 sigma.
void expect_uniform(const Film& film, const Vec3& expected, double k, const std::string& what) {
  Vec3 sum(0, 0, 0), var(0, 0, 0);
  const double n = double(film.width()) * film.height();
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x) {
      const Vec3 m = film.mean(x, y), v = film.variance(x, y);
      for (int c = 0; c < 3; ++c) {
        ASSERT_TRUE(std::isfinite(m[c]) && std::isfinite(v[c])) << what;
        EXPECT_NEAR(m[c], expected[c], k * std::sqrt(v[c]) + 1e-6 * expected[c])
            << what << " pixel " << x << "," << y << " channel " << c;
      }
      sum += m;
      var += v;
    }
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(sum[c] / n, expected[c], 3.0 * std::sqrt(var[c]) / n + 1e-6 * expected[c]) << what << " average";
}

}  // namespace

TEST(RenderFurnace, LambertianSphereRendersAlbedoTimesRadianceForEveryStrategy) {
  const Vec3 L(0.8, 1.0, 1.3), rho(0.7, 0.5, 0.3);
  ConstantEnvironment env(L);
  FurnaceScene furnace(make_diffuse(rho));
  RenderOptions ro;
  ro.spp = 32;
  ro.crop = Crop{3, 3, 9, 9};  // every pixel of this window sees the sphere
  for (const Case& c : all_strategies()) {
    const Integrator integrator(furnace.scene, *env.light, c.options);
    const Film film = render_image(furnace.camera, integrator, ro);
    expect_uniform(film, Vec3(rho.x * L.x, rho.y * L.y, rho.z * L.z), 5.0, c.name);
    EXPECT_EQ(integrator.nonfinite_count(), 0u) << c.name;
  }
}

TEST(RenderFurnace, BackgroundPixelsSeeTheEnvironment) {
  const Vec3 L(0.25, 0.5, 2.0);
  ConstantEnvironment env(L);
  FurnaceScene furnace(make_diffuse(Vec3(0.5)));
  const Camera wide(Vec3(0, 0, -4), Vec3(0, 0, 0), Vec3(0, 1, 0), 90.0, 12, 12);
  RenderOptions ro;
  ro.spp = 2;
  ro.crop = Crop{0, 0, 1, 1};  // a corner: misses the sphere
  const Integrator integrator(furnace.scene, *env.light, IntegratorOptions{});
  const Film film = render_image(wide, integrator, ro);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(film.mean(0, 0)[c], L[c], 1e-6 * L[c]);
}

TEST(RenderFurnace, MirrorSphereReflectsTheEnvironmentInEveryStrategy) {
  const Vec3 L(0.8, 1.0, 1.3), r(0.9, 0.6, 0.3);
  ConstantEnvironment env(L);
  FurnaceScene furnace(make_mirror(r));
  RenderOptions ro;
  ro.spp = 4;
  ro.crop = Crop{3, 3, 9, 9};
  for (const Case& c : all_strategies()) {
    const Integrator integrator(furnace.scene, *env.light, c.options);
    const Film film = render_image(furnace.camera, integrator, ro);
    expect_uniform(film, Vec3(r.x * L.x, r.y * L.y, r.z * L.z), 0.0, std::string("mirror ") + c.name);
  }
}

TEST(RenderFurnace, IndirectBouncesBetweenTwoSpheresStayBounded) {
  // With --max-depth > 1 a diffuse sphere next to another one receives interreflections: still <= L and
  // more than with direct light only.
  const Vec3 L(1.0, 1.0, 1.0);
  ConstantEnvironment env(L);
  Scene scene;
  const int m = scene.add_material("white", make_diffuse(Vec3(0.8)));
  scene.add_sphere(Vec3(-1.05, 0, 0), 1.0, m);
  scene.add_sphere(Vec3(1.05, 0, 0), 1.0, m);
  scene.commit();
  const Camera camera(Vec3(0, 0, -6), Vec3(0, 0, 0), Vec3(0, 1, 0), 30.0, 16, 16);
  RenderOptions ro;
  ro.spp = 64;
  IntegratorOptions direct, bounces;
  bounces.max_depth = 4;
  const Film a = render_image(camera, Integrator(scene, *env.light, direct), ro);
  const Film b = render_image(camera, Integrator(scene, *env.light, bounces), ro);
  double sa = 0, sb = 0;
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) {
      sa += a.mean(x, y).x;
      sb += b.mean(x, y).x;
      EXPECT_LE(b.mean(x, y).x, 1.0 + 6.0 * std::sqrt(b.variance(x, y).x) + 1e-6);
    }
  EXPECT_GT(sb, sa * 1.01);
}

TEST(RenderFurnace, ObjCubeRendersAlbedoTimesRadiance) {
  // A convex OBJ mesh (a cube, quads triangulated by the loader, with vertex normals per face) in a constant
  // environment: every pixel that sees it renders rho L, so triangle hits, normals and the loader are right.
  const auto dir = std::filesystem::temp_directory_path() / ("envkit_render_obj_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "cube.obj")
      << "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
         "vn 0 0 -1\nvn 0 0 1\nvn 0 -1 0\nvn 0 1 0\nvn -1 0 0\nvn 1 0 0\n"
         "f 1//1 4//1 3//1 2//1\nf 5//2 6//2 7//2 8//2\nf 1//3 2//3 6//3 5//3\n"
         "f 4//4 8//4 7//4 3//4\nf 1//5 5//5 8//5 4//5\nf 2//6 3//6 7//6 6//6\n";
  std::ofstream(dir / "cube.json") << R"({
    "camera": {"position": [3, 2.5, -4], "look_at": [0, 0, 0], "fov": 20, "resolution": [16, 16]},
    "environment": {"probe": "constant", "radiance": [0.5, 1.0, 2.0], "size": [32, 16]},
    "materials": {"m": {"type": "diffuse", "albedo": [0.8, 0.5, 0.25]}},
    "shapes": [{"type": "mesh", "file": "cube.obj", "material": "m"}]
  })";
  const LoadedScene scene = load_scene_file((dir / "cube.json").string());
  std::filesystem::remove_all(dir);
  RenderOptions ro;
  ro.spp = 16;
  ro.crop = Crop{6, 6, 10, 10};  // the cube's middle, away from its silhouette
  for (const Case& c : all_strategies()) {
    const Integrator integrator(*scene.scene, *scene.light, c.options);
    const Film film = render_image(scene.camera, integrator, ro);
    expect_uniform(film, Vec3(0.4, 0.5, 0.5), 5.0, std::string("obj cube ") + c.name);
  }
}
