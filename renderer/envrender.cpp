// envrender: renders a scene lit by an environment map through envkit's baked sampling tables.
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/request_limits.h>
#include <envkit/render/integrator.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <envkit/tables/sun_split.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "cli/render_options.h"
#include "common/cli.h"
#include "common/progress.h"

namespace {

namespace tools = envkit::tools;

constexpr const char* kExamples = R"(
Examples:
  envrender                                        the built-in default scene -> envrender.exr + envrender.png
  envrender --scene renderer/scenes/default.json -o out/default.exr --spp 64
  envrender --scene my.json --bake                 bake the environment's tables in memory (no table file)
  envrender --strategy light --light-method alias --light-samples 4
  envrender --strategy mis --heuristic balance --bsdf-samples 1 --light-samples 2
  envrender --sun-samples 0                        sample a sunny map as one table (default: the sun apart)
  envrender --strategy mis-compensated --time 10   render for 10 seconds
  envrender --crop 0,0,240,120 -o tile0.exr        one window of the image (for farms)
  envrender --max-depth 3                          two indirect bounces (caustics after a rough bounce blurred)
  envrender --max-depth 3 --regularize 0           the same, unbiased: exact caustics, noisier on sunny maps
  envrender --strategy product-sh-mis --sh-order 4 --sh-resolution 32   a coarser SH product (faster, noisier)
  envrender --strategy product-wavelet --wavelet-resolution 64 --wavelet-kept 256   finer cells, compressed factors

Output: a linear two-part EXR (part 0: R, G, B; part 1 "aov": variance.R/G/B = variance of each pixel's mean,
samples) and a PNG preview through the OCIO display transform (sRGB, ACES 1.0 - SDR Video) next to it (.png).
Scene format: docs/SCENE_FORMAT.md.
Exit codes: 0 success, 1 bad input or failure (one line on stderr, no output file), 2 usage error.
)";

struct Args {
  std::string scene;
  std::string output = "envrender.exr";
  envkit::render::Strategy strategy = envkit::render::IntegratorOptions{}.strategy;
  envkit::SamplingMethod light_method = envkit::render::IntegratorOptions{}.light_method;
  envkit::render::Heuristic heuristic = envkit::render::IntegratorOptions{}.heuristic;
  std::string crop;
  std::string resolution;
  int spp = 16;
  double time = 0.0;
  std::optional<int> bsdf_samples;  // unset: by the material's lobe (sample_counts())
  std::optional<int> light_samples;
  int sun_samples = envkit::render::IntegratorOptions{}.sun_samples;
  int max_depth = 1;
  double regularize = envkit::render::IntegratorOptions{}.regularization;
  envkit::render::IntegratorOptions seed_samplers;  // the seed samplers' parameters (wavelet, steerable, sh)
  int threads = 0;
  unsigned seed = 0;
  bool bake = false;
  bool force = false;
  bool quiet = false;
  bool progress = false;
  bool pixel_seconds = false;
};

envkit::render::Crop parse_crop(const std::string& text) {
  envkit::render::Crop c;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%d,%d,%d,%d%c", &c.x0, &c.y0, &c.x1, &c.y1, &tail) != 4)
    throw CLI::ValidationError("--crop", "expected x0,y0,x1,y1 (pixels, x1 and y1 exclusive), got '" + text + "'");
  return c;
}

std::string preview_path(const std::string& exr) {
  return std::filesystem::path(exr).replace_extension(".png").string();
}

int run(const Args& a) {
  using namespace envkit::render;
  namespace tools = envkit::tools;
  if (std::filesystem::path(a.output).extension() != ".exr")
    throw envkit::Error(a.output + ": the output must be an .exr file (the PNG preview is written next to it)");
  const std::string png = preview_path(a.output);
  std::vector<std::string> inputs;
  if (!a.scene.empty()) inputs.push_back(a.scene);
  envkit::check_outputs({a.output, png}, inputs, a.force);
  auto thread_limit = tools::limit_threads(a.threads);

  SceneLoadOptions load;
  load.bake = a.bake;
  if (!a.resolution.empty()) {
    // The scene format's limit, checked before the scene is loaded and anything is allocated.
    const tools::ImageSize size = tools::parse_image_size("--resolution", a.resolution, 16384);
    load.width = size.width;
    load.height = size.height;
    tools::check_request("--resolution", a.resolution, [&] { check_render_size(load.width, load.height); });
  }
  LoadedScene scene = a.scene.empty() ? make_default_scene(load) : load_scene_file(a.scene, load);
  // The environment image (its six faces for a '%' pattern) is an input too: never replace it. The loader names it
  // in environment_description ("probe ..." for a generated environment, which is no file).
  for (const std::string& image : envkit::face_paths(scene.environment_description)) inputs.push_back(image);
  envkit::check_outputs({a.output, png}, inputs, a.force);
  IntegratorOptions io;
  io.strategy = a.strategy;
  io.light_method = a.light_method;
  io.heuristic = a.heuristic;
  io.bsdf_samples = a.bsdf_samples;
  io.light_samples = a.light_samples;
  io.sun_samples = a.sun_samples;
  io.max_depth = a.max_depth;
  io.regularization = a.regularize;
  io.wavelet = a.seed_samplers.wavelet;
  io.steerable = a.seed_samplers.steerable;
  io.sh = a.seed_samplers.sh;
  if (!a.quiet) {
    for (const std::string& note : scene.notes) tools::info(note);
    // A warning about the compensated tables matters only to the strategy that draws from them.
    for (const envkit::TableWarning& w : scene.tables->warnings())
      if (io.strategy == Strategy::MisCompensated || !w.concerns_compensated_tables()) tools::warn(w.message);
  }
  const auto setup_start = std::chrono::steady_clock::now();
  const Integrator integrator = [&] {
    try {
      return Integrator(*scene.scene, *scene.light, io, &scene.camera);
    } catch (const IntegratorOptionsError& e) {
      // The library names fields; the user typed options.
      throw envkit::Error(e.message(envkit::render::cli::option_flag));
    }
  }();
  const double setup_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - setup_start).count();
  std::vector<std::string> setup_notes;
  if (const envkit::SunSplit* sun = integrator.sun_split()) {
    const envkit::Vec3 d = envkit::apply(scene.light->rotation(), sun->sun().direction);
    setup_notes.push_back("sampling the sun apart from the rest of the map: " + std::to_string(sun->sun().texels) +
                          " texels at elevation " +
                          tools::fmt(std::asin(std::clamp(d.y, -1.0, 1.0)) * 180.0 / envkit::kPi, 3) + " deg, " +
                          tools::fmt(100.0 * sun->sun().power_share, 3) + "% of the light, " +
                          std::to_string(a.sun_samples) + " sample(s) per shading point");
    const bool compensated = io.strategy == Strategy::MisCompensated;
    if (scene.tables->stored_sun_split(io.light_method, compensated).has_value())
      setup_notes.back() += ", the split read from " + scene.tables->file_path();
    else if (!scene.tables->file_path().empty())
      setup_notes.back() += std::string(" (split at load; envbake --tables ") + envkit::method_name(io.light_method) +
                            (compensated ? ",compensated" : "") + ",sun stores it with the tables)";
  }
  if (integrator.has_product_tables())
    setup_notes.push_back("product tables for the scene's " + std::to_string(integrator.product_lobe_count()) +
                          " lobe shape(s) (" + tools::fmt(double(integrator.product_table_bytes()) / (1 << 20), 3) +
                          " MiB)");
  if (io.strategy == Strategy::Auto && integrator.has_product_tables()) {
    std::string chosen;
    for (int m = 0; m < scene.scene->material_count(); ++m) {
      const envkit::render::LightChoice c = integrator.light_choice(m);
      if (scene.scene->material(m).is_pure_delta()) continue;
      chosen += (chosen.empty() ? "" : ", ") + scene.scene->material_names()[std::size_t(m)] + ": " +
                (c.product ? "product table" : "plain table") + (c.sun_apart ? " + sun" : "");
    }
    setup_notes.push_back("light per material (pilot): " + chosen);
  }
  if (const envkit::render::ProductWavelet* w = integrator.product_wavelet())
    setup_notes.push_back("wavelet product tables, " + std::to_string(w->options().resolution) + "^2 cells (" +
                          tools::fmt(double(w->bytes()) / (1 << 20), 3) + " MiB)");
  if (const envkit::render::ProductSteerable* p = integrator.product_steerable())
    setup_notes.push_back("steerable product tables, SH order " + std::to_string(p->options().order) + ", " +
                          std::to_string(p->options().resolution) + "^2 cells (" +
                          tools::fmt(double(p->bytes()) / (1 << 20), 3) + " MiB)");
  if (const envkit::render::ProductSh* p = integrator.product_sh())
    setup_notes.push_back("SH product tables, order " + std::to_string(p->options().order) + ", " +
                          std::to_string(p->options().resolution) + "^2 cells (" +
                          tools::fmt(double(p->bytes()) / (1 << 20), 3) + " MiB)");
  if (!setup_notes.empty() && !a.quiet) {
    setup_notes.back() += " (built in " + tools::fmt(setup_ms, 3) + " ms)";
    for (const std::string& note : setup_notes) tools::info(note);
  }
  // A clipped sun renders: its direction is right, its power is what the camera kept (too little).
  if (const envkit::SunSplit* sun = integrator.sun_split(); sun && sun->sun().clipped)
    tools::warn(scene.environment_description + ": the sun is clipped flat (" +
                std::to_string(sun->sun().clipped_texels) + " of its " + std::to_string(sun->sun().texels) +
                " texels share its maximum value): the map holds too little of its power, sunlit surfaces render "
                "too dark");

  RenderOptions ro;
  ro.spp = a.spp;
  ro.time_seconds = a.time;
  ro.seed = a.seed;
  ro.pixel_seconds = a.pixel_seconds;
  if (!a.crop.empty()) ro.crop = parse_crop(a.crop);
  const std::size_t work = std::size_t(scene.camera.width()) * scene.camera.height() * std::size_t(std::max(a.spp, 1));
  tools::ProgressBar bar("rendering",
                         tools::want_progress(a.progress, a.quiet, a.time > 0 ? (std::size_t(1) << 30) : work));
  ro.progress = [&bar](double f) { bar.update(f); };
  RenderStats stats;
  const Film film = render_image(scene.camera, integrator, ro, &stats);
  bar.finish();
  if (integrator.nonfinite_count() > 0)
    tools::warn(std::to_string(integrator.nonfinite_count()) + " non-finite estimates replaced by 0");

  std::map<std::string, std::string> meta = {
      {"envkit:renderer", "envrender"},
      {"envkit:scene", a.scene.empty() ? "built-in default" : a.scene},
      {"envkit:strategy", strategy_name(a.strategy)},
      {"envkit:light_method", envkit::method_name(io.light_method)},
      {"envkit:heuristic", heuristic_name(a.heuristic)},
      {"envkit:bsdf_samples", a.bsdf_samples ? std::to_string(*a.bsdf_samples) : "by lobe"},
      {"envkit:light_samples", a.light_samples ? std::to_string(*a.light_samples) : "by lobe"},
      {"envkit:sun_samples", std::to_string(integrator.sun_split() ? a.sun_samples : 0)},
      {"envkit:max_depth", std::to_string(a.max_depth)},
      {"envkit:regularize", tools::fmt(a.regularize, 6)},
      {"envkit:spp", std::to_string(stats.spp)},
      {"envkit:seed", std::to_string(a.seed)},
      {"envkit:seconds", tools::fmt(stats.seconds, 4)},
      {"envkit:environment", scene.environment_description}};
  // The EXR and its preview are one output: both appear, or neither (also on a signal, a full disk or ulimit -f).
  envkit::OutputGroup outputs;
  film.write_exr(a.output, meta);
  film.write_preview(png);
  outputs.commit();
  if (!a.quiet) {
    std::ostringstream msg;
    msg << "wrote " << a.output << " and " << png << " (" << film.width() << "x" << film.height() << ", " << stats.spp
        << " spp, " << strategy_name(a.strategy) << ", " << tools::fmt(stats.seconds, 3) << " s, "
        << tools::fmt(double(stats.samples) / std::max(stats.seconds, 1e-9) * 1e-6, 3) << " M camera samples/s)";
    tools::info(msg.str());
  }
  return envkit::tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("envrender: render a scene lit by an environment map through envkit's baked sampling tables",
               "envrender");
  app.footer(kExamples);
  Args a;
  app.add_option("--scene", a.scene, "JSON scene file (docs/SCENE_FORMAT.md); default: the built-in scene")
      ->check([](const std::string& path) { return path.empty() ? std::string("empty path") : std::string(); });
  app.add_option("-o,--output", a.output, "output EXR (the PNG preview goes next to it)")->capture_default_str();
  app.add_option("--spp", a.spp, "samples per pixel")->transform(tools::integer_in(1, 1 << 24))->capture_default_str();
  app.add_option("--time", a.time, "render for this many seconds instead of --spp (passes of 1 spp)")
      ->check(tools::number_in(0.0, 1e6, true));
  tools::add_parsed_option(
      app, "--strategy", a.strategy, envkit::render::parse_strategy,
      envkit::render::strategy_names("|") +
          " (auto: as product-mis, with each material's table, product or plain, and the sun apart or not "
          "chosen by a short pilot; product-wavelet: Clarberg et al. 2005's wavelet product of lighting and "
          "BSDF; product-steerable: Subr and Arvo 2007's per-basis lighting tables; product-sh: Jarosz et al. "
          "2009's SH product; each the whole map)")
      ->default_str(envkit::render::strategy_name(a.strategy));
  tools::add_parsed_option(app, "--light-method", a.light_method, envkit::parse_method,
                           "environment sampling table of light, mis and mis-compensated: cdf|alias|hierarchical "
                           "(the product strategies refine the hierarchical table)")
      ->default_str(envkit::method_name(a.light_method));
  tools::add_parsed_option(app, "--heuristic", a.heuristic, envkit::render::parse_heuristic,
                           "MIS heuristic: balance|power")
      ->default_str(envkit::render::heuristic_name(a.heuristic));
  const std::string narrow = tools::fmt(envkit::render::kWideLobeAlpha, 3);
  app.add_option("--bsdf-samples", a.bsdf_samples,
                 "BSDF samples per shading point (N) for every material; default: by the material's lobe, " +
                     std::to_string(envkit::render::kNarrowBsdfSamples) +
                     " for materials with a lobe narrower than GGX alpha " + narrow +
                     " (a glossy metal or coat), "
                     "else 1 (powers of two stratify best); with --max-depth > 1, " +
                     std::to_string(envkit::render::kPathBsdfSamples) + " for every material")
      ->transform(tools::integer_in(0, 1024));
  app.add_option("--light-samples", a.light_samples,
                 "light (or product) samples per shading point (M) for every material; default: by the material's "
                 "lobe, " +
                     std::to_string(envkit::render::kWideLightSamples) +
                     " for materials whose lobes are all at least as wide as GGX alpha " + narrow +
                     " (Lambertian, rough metal) and " + std::to_string(envkit::render::kNarrowLightSamples) +
                     " for the others; with --max-depth > 1, " + std::to_string(envkit::render::kPathLightSamples) +
                     " for every material")
      ->transform(tools::integer_in(0, 1024));
  app.add_option("--sun-samples", a.sun_samples,
                 "light, mis, mis-compensated, product, product-mis: samples of the map's sun per shading point, drawn "
                 "apart from the rest of the map, at materials whose widest lobe is at least GGX alpha " +
                     tools::fmt(envkit::render::kSunSampleAlpha, 3) +
                     " (0 = sample the map as one table; ignored when the map has no sun)")
      ->transform(tools::integer_in(0, 1024))
      ->capture_default_str();
  app.add_option("--max-depth", a.max_depth, "scattering events per path (1 = direct light only)")
      ->transform(tools::integer_in(1, 64))
      ->capture_default_str();
  app.add_option("--regularize", a.regularize,
                 "BIASED noise reduction for --max-depth > 1 (Cycles' Filter Glossy rule): after a diffuse or rough "
                 "bounce, glossy and mirror lobes are widened, up to GGX alpha 0.5 and the more the larger the "
                 "value, so the image converges to a slightly blurred one (Cycles' default is 1); 0 = unbiased")
      ->check(tools::number_in(0.0, 1e6))
      ->capture_default_str();
  envkit::render::cli::add_seed_sampler_options(app, a.seed_samplers);
  app.add_option("--crop", a.crop, "render only the window x0,y0,x1,y1 (pixels, x1/y1 exclusive)");
  app.add_option("--resolution", a.resolution, "override the camera resolution, WxH");
  app.add_option("--seed", a.seed, "sampler seed")
      ->transform(tools::integer_in(0, 4294967295LL))
      ->capture_default_str();
  app.add_flag("-f,--force", a.force, "allow the output (or its PNG preview) to replace an input file");
  app.add_flag("--bake", a.bake, "bake missing or stale sampling tables in memory instead of failing");
  envkit::tools::add_threads_option(app, a.threads);
  app.add_flag("--pixel-seconds", a.pixel_seconds,
               "add a channel `seconds` to the EXR's aov part: the CPU time spent on each pixel's samples (what a "
               "region of the image cost; it differs from run to run)");
  app.add_flag("--progress", a.progress, "always show the progress bar");
  app.add_flag("-q,--quiet", a.quiet, "print errors only");
  return envkit::tools::run_cli(app, argc, argv, [&] { return run(a); });
}
