// envproduct: what each sampling strategy draws at one shading point: BRDF x cos, the lighting and their product over
// the sphere of directions, with every strategy's samples as dots over them (the seed lecture's last figure, for
// any map, material, normal and view).
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/core/input_checks.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/image_io.h>
#include <envkit/render/integrator.h>
#include <envkit/render/scene_loader.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli/render_options.h"
#include "cli/sphere_pictures.h"
#include "common/cli.h"
#include "common/progress.h"

namespace {

namespace tools = envkit::tools;
namespace render = envkit::render;
namespace fs = std::filesystem;

constexpr const char* kDefaultStrategies = "bsdf,light,product,product-wavelet,product-steerable,product-sh";

constexpr const char* kFooter = R"(
The figure (-o, PNG): panels of one size, three to a row, each a lat-long of the scene's world frame (+Y up, the
frame --normal and --view are given in; the image centre looks along +Z, as envsample's pictures):
  row 1: BRDF x cos (f(wo, wi) cos theta_i; black below the surface), the lighting (the map as the scene sees it,
         rotation included), and their product, the integrand of the point's direct light;
  then one panel per strategy: its -n samples as red dots over the picture of what it aims at (bsdf over BRDF x cos,
         light over the lighting, every other over the product), dimmed to 40%.
Each picture is scaled on its own: colour kept, luminance Y shown as log(1 + Y / mean) / log(1 + max / mean).
A strategy's samples are drawn through the renderer's own code (Integrator::strategy_at): each of its techniques
(BSDF, light table, sun, product table, seed sampler) in proportion to its samples per shading point, as envrender
draws them; MIS strategies show both techniques' samples.

--exr PREFIX also writes linear float lat-longs: PREFIX.brdf.exr, PREFIX.lighting.exr, PREFIX.product.exr (RGB, the
product texel-wise brdf x lighting) and PREFIX.samples.<strategy>.exr (R: the samples' density per steradian,
count / (n x texel solid angle); G: the strategy's pdf per steradian, averaged over the texel; R converges to G as
-n grows).

Examples:
  envproduct                                   the default probe, material rough030, normal +Y, view 45 deg
  envproduct --material '{"type": "measured", "file": "blue-fabric.binary"}' --env probe.exr -o fabric.png
        the seed's figure: the MERL "Blue Fabric" under a light probe (MERL files are not shipped: get
        blue-fabric.binary from the MERL BRDF database, https://www.merl.com/brdf/)
  envproduct --material '{"type": "conductor", "roughness": 0.05}' --env '{"probe": "sun", "elevation_deg": 30}'
  envproduct --material rough010 --normal 1,1,0 --view 0,1,-1 -n 4096 --strategies bsdf,mis,auto
  envproduct -n 1000000 --exr out/density --strategies product-sh --sh-order 4

Exit status: 0 success; 1 bad input (one line on stderr naming the file or option, no output written); 2 usage error.)";

struct Args {
  std::string env, material = "rough030", normal = "0,1,0", view = "0,1,-1", output = "envproduct.png", exr;
  std::string strategies = kDefaultStrategies;
  std::size_t n = 256;
  int width = 512;
  std::uint32_t seed = 0;
  int threads = 0;
  bool force = false, quiet = false, progress = false;
  render::IntegratorOptions seed_samplers;
};

/// "x,y,z": three finite numbers, not all zero; normalised.
envkit::Vec3 parse_direction(const std::string& option, const std::string& text) {
  std::vector<std::string> parts;
  std::stringstream in(text);
  for (std::string part; std::getline(in, part, ',');) parts.push_back(part);
  if (parts.size() != 3 || text.back() == ',')
    throw CLI::ValidationError(option, "expected x,y,z (three numbers), got '" + text + "'");
  envkit::Vec3 d;
  for (int i = 0; i < 3; ++i) d[i] = tools::parse_number(option, parts[std::size_t(i)], -1e6, 1e6);
  if (!(d.length2() > 0.0)) throw CLI::ValidationError(option, "'" + text + "' is the zero vector");
  return d / std::sqrt(d.length2());
}

std::vector<render::Strategy> parse_strategies(const std::string& text) {
  std::vector<render::Strategy> list;
  std::stringstream in(text);
  for (std::string name; std::getline(in, name, ',');) try {
      list.push_back(render::parse_strategy(name));
    } catch (const envkit::Error& e) {
      throw CLI::ValidationError("--strategies", e.what());
    }
  if (list.empty()) throw CLI::ValidationError("--strategies", "names no strategy");
  return list;
}

bool is_json(const std::string& text) {
  const std::size_t first = text.find_first_not_of(" \t\r\n");
  return first != std::string::npos && text[first] == '{';
}

std::string read_file(const std::string& path, const std::string& option) {
  if (!fs::exists(path)) throw envkit::Error(option + ": '" + path + "': no such file");
  envkit::require_regular_file(path);
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in && !in.eof()) throw envkit::Error(path + ": cannot read");
  return text.str();
}

/// The built-in default scene's JSON (its presets and its environment).
const nlohmann::json& default_scene() {
  static const nlohmann::json scene = nlohmann::json::parse(render::default_scene_json());
  return scene;
}

/// --material: JSON text, a preset (a material of the default scene) or a JSON file; its file joins `inputs`.
std::unique_ptr<render::Material> load_material(const std::string& spec, std::vector<std::string>& inputs) {
  if (is_json(spec)) return render::load_material_text(spec, "--material");
  const nlohmann::json& presets = default_scene()["materials"];
  if (presets.contains(spec)) return render::load_material_text(presets[spec].dump(), "<preset " + spec + ">");
  if (!fs::exists(spec)) {
    std::string names;
    for (const auto& [name, value] : presets.items()) names += (names.empty() ? "" : ", ") + name;
    throw envkit::Error("--material: '" + spec + "' is neither JSON, a preset (" + names + ") nor a file");
  }
  inputs.push_back(spec);
  return render::load_material_text(read_file(spec, "--material"), spec);
}

/// --env: JSON text of a scene's environment entry, or an image file; default: the default scene's probe. Tables
/// are baked in memory unless the JSON names a fresh table file.
render::LoadedScene load_environment(const std::string& spec) {
  render::SceneLoadOptions options;
  options.bake = true;
  if (spec.empty())
    return render::load_environment_text(default_scene()["environment"].dump(), "<built-in default probe>", options);
  if (is_json(spec)) return render::load_environment_text(spec, "--env", options);
  return render::load_environment_text(nlohmann::json{{"image", spec}}.dump(), "--env", options);
}

std::string lower_extension(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

/// render::validate(), its refusal in the flags' words.
void check_options(const render::IntegratorOptions& options) {
  try {
    render::validate(options);
  } catch (const render::IntegratorOptionsError& e) {
    throw envkit::Error(e.message(render::cli::option_flag));
  }
}

/// The integrator of one strategy over the one-material scene (its options checked by check_options()).
std::unique_ptr<render::Integrator> make_integrator(const render::Scene& scene, const render::EnvironmentLight& light,
                                                    render::IntegratorOptions options, render::Strategy strategy) {
  options.strategy = strategy;
  return std::make_unique<render::Integrator>(scene, light, options);
}

void write_exr(const std::string& path, const envkit::Image& image, const std::string& description) {
  envkit::WriteOptions wo;
  wo.metadata["envkit:description"] = description;
  wo.metadata["envkit:parameterization"] = "latlong";
  envkit::write_image(path, image, wo);
}

int run(const Args& a) {
  const std::string ext = lower_extension(a.output);
  if (ext != ".png") throw CLI::ValidationError("--output", "'" + a.output + "': the figure is a .png file");
  const envkit::Vec3 normal = parse_direction("--normal", a.normal), view = parse_direction("--view", a.view);
  if (!((normal ^ view) > 0.0))
    throw CLI::ValidationError("--view", "points below the surface (--view . --normal must be > 0)");
  const std::vector<render::Strategy> strategies = parse_strategies(a.strategies);
  for (render::Strategy s : strategies) {
    render::IntegratorOptions options = a.seed_samplers;
    options.strategy = s;
    check_options(options);  // before anything is loaded
  }
  std::vector<std::string> outputs = {a.output};
  if (!a.exr.empty()) {
    for (const char* part : {"brdf", "lighting", "product"}) outputs.push_back(a.exr + "." + part + ".exr");
    for (render::Strategy s : strategies) outputs.push_back(a.exr + ".samples." + render::strategy_name(s) + ".exr");
  }
  std::vector<std::string> inputs;
  envkit::check_outputs(outputs, inputs, a.force);
  auto thread_limit = tools::limit_threads(a.threads);

  render::Scene scene;
  scene.add_material("material", load_material(a.material, inputs));
  scene.commit();
  render::LoadedScene env = load_environment(a.env);
  for (const std::string& image : envkit::face_paths(env.environment_description)) inputs.push_back(image);
  envkit::check_outputs(outputs, inputs, a.force);  // now that every input file is known
  envkit::install_temp_cleanup_on_signal();

  const render::Frame frame = render::Frame::from_normal(normal);
  const render::cli::PointView point{frame, frame.to_local(view), &scene.material(0)};
  const envkit::LatLongMap map(a.width, a.width / 2);
  const render::cli::SpherePictures pictures = render::cli::sphere_pictures(map, point, *env.light);
  const envkit::Image shown[3] = {render::cli::display_picture(pictures.brdf_cos),
                                  render::cli::display_picture(pictures.lighting),
                                  render::cli::display_picture(pictures.product)};
  std::vector<envkit::Image> dotted, densities;
  dotted.reserve(strategies.size());
  tools::ProgressBar bar("sampling", tools::want_progress(a.progress, a.quiet, a.n * strategies.size()));
  for (std::size_t i = 0; i < strategies.size(); ++i) {
    const auto start = std::chrono::steady_clock::now();
    const auto integrator = make_integrator(scene, *env.light, a.seed_samplers, strategies[i]);
    const render::Integrator::StrategyDistribution strategy =
        integrator->strategy_at(frame, point.wo_local, *point.material);
    const render::cli::StrategySamples samples = render::cli::draw_samples(strategy, map, a.n, a.seed);
    const int target = strategies[i] == render::Strategy::Bsdf ? 0 : strategies[i] == render::Strategy::Light ? 1 : 2;
    dotted.push_back(render::cli::dotted_picture(shown[target], map, samples.directions));
    if (!a.exr.empty()) densities.push_back(render::cli::density_picture(map, samples, strategy));
    bar.update(double(i + 1) / double(strategies.size()));
    if (!a.quiet) {
      std::string note =
          std::string(render::strategy_name(strategies[i])) + ": " + std::to_string(a.n) + " draws in " +
          tools::fmt(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 3) +
          " s (tables included)";
      if (samples.none > 0) note += ", " + std::to_string(samples.none) + " gave no direction (below the horizon)";
      if (samples.delta > 0) note += ", " + std::to_string(samples.delta) + " of a delta lobe";
      tools::info(note);
    }
  }
  bar.finish();

  std::vector<render::cli::Panel> panels = {{&shown[0], "BRDF x cos"},
                                            {&shown[1], "lighting"},
                                            {&shown[2], "product (dots: " + std::to_string(a.n) + " samples)"}};
  for (std::size_t i = 0; i < strategies.size(); ++i)
    panels.push_back({&dotted[i], render::strategy_name(strategies[i])});
  bool labelled = true;
  const envkit::Image figure = render::cli::compose_figure(panels, 3, &labelled);
  if (!labelled && !a.quiet) tools::warn("no font for the panels' labels: panels in the order of --help, unlabelled");

  envkit::OutputGroup group;
  envkit::WriteOptions png;
  png.metadata["envkit:description"] = "envproduct: BRDF x cos, lighting, product; then " + a.strategies;
  envkit::write_image(a.output, figure, png);
  if (!a.exr.empty()) {
    write_exr(outputs[1], pictures.brdf_cos, "BRDF x cos (RGB, per steradian)");
    write_exr(outputs[2], pictures.lighting, "lighting (RGB radiance)");
    write_exr(outputs[3], pictures.product, "BRDF x cos x lighting (RGB)");
    for (std::size_t i = 0; i < strategies.size(); ++i)
      write_exr(outputs[4 + i], densities[i], "R: sample density per steradian, G: pdf per steradian");
  }
  group.commit();
  if (!a.quiet)
    tools::info("wrote " + a.output +
                (a.exr.empty() ? "" : " and " + std::to_string(outputs.size() - 1) + " EXR files"));
  return tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app(
      "envproduct: what each sampling strategy draws at one shading point: BRDF x cos, the lighting and their "
      "product over the sphere, with each strategy's samples",
      "envproduct");
  app.footer(kFooter);
  Args a;
  app.add_option("--env", a.env,
                 "environment: an image file (any map envrender reads; tables baked in memory) or the JSON of a "
                 "scene's \"environment\" entry (docs/SCENE_FORMAT.md); default: the built-in default probe as "
                 "envrender's default scene lights it");
  app.add_option("--material", a.material,
                 "material: a preset (the default scene's: ground, matte, rough001, rough005, rough010, rough030, "
                 "rough050), the JSON of a scene's material entry, or a file holding that JSON")
      ->capture_default_str();
  app.add_option("--normal", a.normal, "the shading normal x,y,z (world frame, +Y up)")->capture_default_str();
  app.add_option("--view", a.view, "the direction from the point towards the viewer x,y,z (world frame)")
      ->capture_default_str();
  app.add_option("-n,--samples", a.n, "samples per strategy")
      ->transform(tools::integer_in(1, 100000000))
      ->capture_default_str();
  app.add_option("--strategies", a.strategies, "comma-separated envrender strategies to draw from")
      ->capture_default_str();
  app.add_option("-o,--output", a.output, "the figure (.png)")->capture_default_str();
  app.add_option("--exr", a.exr, "also write PREFIX.brdf/lighting/product.exr and PREFIX.samples.<strategy>.exr")
      ->type_name("PREFIX");
  app.add_option("--width", a.width, "panel width in texels (height = width / 2)")
      ->transform(tools::integer_in(16, 4096))
      ->capture_default_str();
  app.add_option("--seed", a.seed, "seed of the samples' Sobol points")
      ->transform(tools::integer_in(0, 4294967295LL))
      ->capture_default_str();
  render::cli::add_seed_sampler_options(app, a.seed_samplers);
  tools::add_threads_option(app, a.threads);
  app.add_flag("-f,--force", a.force, "allow an output to replace an input file");
  app.add_flag("--progress", a.progress, "always show the progress bar");
  app.add_flag("-q,--quiet", a.quiet, "print errors only");
  return tools::run_cli(app, argc, argv, [&] { return run(a); });
}
