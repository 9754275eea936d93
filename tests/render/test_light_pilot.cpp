// Strategy auto's pilot (light_pilot.cpp): without a camera auto is product-mis, pixel for pixel; with one, each
// material's choice depends on the scene alone, not on the thread count, and weighs the colour channels alike.
// (Unbiasedness, crop and tile independence and finiteness under a 1e6 sun: test_render_strategies.cpp, which
// renders auto beside every other strategy.)
#include <envkit/render/integrator.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "render_support.h"

using namespace envkit;
using namespace envkit::render;

namespace {

LoadedScene small_default_scene(int width, int height) {
  SceneLoadOptions options;
  options.width = width;
  options.height = height;
  std::string text = default_scene_json();
  const std::string from = R"("probe": "default", "size": [1024, 512])";
  text.replace(text.find(from), from.size(), R"("probe": "default", "size": [256, 128])");
  return load_scene_text(text, "pilot.json", options);
}

IntegratorOptions with(Strategy s) {
  IntegratorOptions o;
  o.strategy = s;
  return o;
}

TEST(LightPilot, WithoutACameraAutoIsProductMis) {
  const LoadedScene scene = small_default_scene(24, 12);
  const Integrator automatic(*scene.scene, *scene.light, with(Strategy::Auto));
  const Integrator product(*scene.scene, *scene.light, with(Strategy::ProductMis));
  for (int m = 0; m < scene.scene->material_count(); ++m)
    EXPECT_EQ(automatic.light_choice(m), product.light_choice(m)) << m;
  RenderOptions ro;
  ro.spp = 2;
  const Film a = render_image(scene.camera, automatic, ro), b = render_image(scene.camera, product, ro);
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x) ASSERT_EQ(a.mean(x, y), b.mean(x, y)) << x << "," << y;
}

TEST(LightPilot, ChoicesDoNotDependOnTheThreadCount) {
  const LoadedScene scene = small_default_scene(48, 24);
  std::vector<LightChoice> many, one;
  {
    const Integrator integrator(*scene.scene, *scene.light, with(Strategy::Auto), &scene.camera);
    for (int m = 0; m < scene.scene->material_count(); ++m) many.push_back(integrator.light_choice(m));
  }
  {
    tbb::global_control serial(tbb::global_control::max_allowed_parallelism, 1);
    const Integrator integrator(*scene.scene, *scene.light, with(Strategy::Auto), &scene.camera);
    for (int m = 0; m < scene.scene->material_count(); ++m) one.push_back(integrator.light_choice(m));
  }
  EXPECT_EQ(many, one);
}

TEST(LightPilot, ExplicitStrategiesKeepTheirRule) {
  // The pilot chooses for auto only: product-mis and mis keep the sun by takes_sun_samples(), with and without a
  // camera.
  const LoadedScene scene = small_default_scene(24, 12);
  for (Strategy s : {Strategy::Mis, Strategy::ProductMis}) {
    const Integrator integrator(*scene.scene, *scene.light, with(s), &scene.camera);
    for (int m = 0; m < scene.scene->material_count(); ++m) {
      const Material& material = scene.scene->material(m);
      EXPECT_EQ(integrator.light_choice(m), (LightChoice{s == Strategy::ProductMis, takes_sun_samples(material)}))
          << strategy_name(s) << " " << m;
    }
  }
}

/// A sunny scene lit in one colour channel only (`channel`: 0 red, 2 blue): the sun and the sky hold their radiance
/// there, the materials are grey (the conductors too: the default conductor is gold, brighter in red than in blue,
/// and would make the two scenes differ). Its maps differ from one channel to another only in the channel the
/// radiance sits in, so every candidate draws the same directions with the same densities in both.
LoadedScene one_channel_scene(int channel) {
  const auto rgb = [channel](double v) {
    std::string out = "[";
    out += channel == 0 ? std::to_string(v) : "0";
    out += ", 0, ";
    out += channel == 2 ? std::to_string(v) : "0";
    return out + "]";
  };
  std::string text = R"({"camera": {"position": [0, 1.6, -7.5], "look_at": [0, 0.55, 0], "resolution": [48, 24]},
    "environment": {"probe": "sun", "size": [256, 128], "elevation_deg": 20, "radius_deg": 1.5, "radiance": )";
  text += rgb(300.0) + R"(, "sky": )" + rgb(0.2) + R"(},
    "materials": {"ground": {"type": "diffuse", "albedo": 0.5},
                  "c005": {"type": "conductor", "eta": 1.5, "k": 3, "roughness": 0.05},
                  "c030": {"type": "conductor", "eta": 1.5, "k": 3, "roughness": 0.3},
                  "p010": {"type": "plastic", "diffuse": 0.4, "roughness": 0.1}},
    "shapes": [{"type": "triangles", "material": "ground", "vertices": [[-50, 0, -50], [50, 0, -50], [50, 0, 50],
                [-50, 0, 50]], "triangles": [[0, 2, 1], [0, 3, 2]]},
               {"type": "sphere", "center": [-1.3, 0.55, 0], "radius": 0.55, "material": "c005"},
               {"type": "sphere", "center": [0, 0.55, 0], "radius": 0.55, "material": "c030"},
               {"type": "sphere", "center": [1.3, 0.55, 0], "radius": 0.55, "material": "p010"}]})";
  return load_scene_text(text, "one_channel.json", SceneLoadOptions{});
}

TEST(LightPilot, WeighsTheColourChannelsAlike) {
  // The images are judged by relMSE over every channel, each against its own mean: a scene lit in red alone and the
  // same scene lit in blue alone have the same errors in their lit channel and must get the same choices. (A score
  // on the luminance sees the blue scene three times dimmer than the red one, so that relMSE's floor weighs its
  // points otherwise.)
  std::vector<LightChoice> choices[2];
  for (int k = 0; k < 2; ++k) {
    const LoadedScene scene = one_channel_scene(2 * k);
    const Integrator integrator(*scene.scene, *scene.light, with(Strategy::Auto), &scene.camera);
    for (int m = 0; m < scene.scene->material_count(); ++m) choices[k].push_back(integrator.light_choice(m));
  }
  EXPECT_EQ(choices[0], choices[1]);
}

}  // namespace
