// envprobe: writes analytic environments (closed-form power) and the built-in default probe.
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/param_factory.h>
#include <envkit/probes.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "common/cli.h"

namespace {

using envkit::Error;
using envkit::Vec3;
namespace probes = envkit::probes;
namespace tools = envkit::tools;

// Radiance and colour components: finite, >= 0 and representable in a float file.
constexpr double kMaxRadiance = 3.4e38;
// --size: the widest and tallest map written.
constexpr int kMaxSide = 65536;
// Checker probe: cell integrals over the whole map beyond one per texel; 2^28 more is a few seconds on 2 cores.
constexpr double kMaxCheckerPieces = 268435456.0;
// Checker probe on maps without exact integrals: background samples along the cells' edges (2^27 is about ten
// seconds on one core).
constexpr double kMaxEdgeEvaluations = 134217728.0;

const char* kExamples = R"(Examples:
  envprobe default -o sky.exr                           built-in outdoor sky, 1024x512 lat-long
  envprobe default -o sky.exr --preview sky.png         ...plus a tone-mapped PNG to look at
  envprobe sun -o sun.exr --radiance 1e5 --radius-deg 0.05 --elevation-deg 30 --azimuth-deg -60
  envprobe constant -o white.exr --param cube --size 64 --radiance 1
  envprobe gradient -o grad.exr --base 0.1,0.2,0.4 --gain 1,0.8,0.5 --form quadratic
  envprobe texel -o texel.exr --size 64x32 --texel 10,5 --radiance 1000 --floor 0.01
  envprobe checker -o checker.exr --cells 8,16 --json
Kinds and their options:
  constant  --radiance                     L = radiance; power 4 pi L
  gradient  --base --gain --form           L = base + gain y^2 (quadratic) or base + gain max(y,0) (upper)
  sun       --radiance --sky --radius-deg --elevation-deg --azimuth-deg | --direction
            power = Ls 2 pi (1 - cos a) + Lsky (4 pi - 2 pi (1 - cos a))
  texel     --texel --radiance --floor     one texel of the output map; power = V Omega + floor (4 pi - Omega)
  checker   --cells --color-a --color-b    n_theta x n_phi cells in (theta, u)
  default   --seed --cloud-cover and the sun options
Azimuth is the lat-long longitude: 0 = +Z (image centre), 90 = +X, -90 = -X. Elevation is above the XZ plane.
The total power printed is the closed form (numerical for the default probe); the written map's own power
(sum of L x texel solid angle) is printed next to it.)";

Vec3 parse_rgb(const std::string& option, const std::string& text, double lo = 0.0, double hi = kMaxRadiance) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) v.push_back(tools::parse_number(option, item, lo, hi));
  if (v.size() == 1) return Vec3(v[0]);
  if (v.size() == 3) return Vec3(v[0], v[1], v[2]);
  throw Error(option + ": '" + text + "' must be one number or R,G,B");
}

std::pair<int, int> parse_pair(const std::string& option, const std::string& text, char sep, int lo, int hi) {
  const auto pos = text.find(sep);
  if (pos == std::string::npos) throw Error(option + ": '" + text + "' must be two integers like 3" + sep + "4");
  return {int(tools::parse_integer(option, text.substr(0, pos), lo, hi)),
          int(tools::parse_integer(option, text.substr(pos + 1), lo, hi))};
}

std::string rgb_text(const Vec3& v) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g", v.x, v.y, v.z);
  return buf;
}

nlohmann::json rgb_json(const Vec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); }

struct Args {
  std::string kind, output, size, grid, basis;
  envkit::Kind param = envkit::Kind::LatLong;
  std::optional<envkit::CubeLayout> layout;
  const envkit::Convention* convention = &envkit::convention("envkit");
  std::string radiance, sky, floor, base, gain, form = "upper", direction, texel, cells, color_a, color_b;
  std::string preview;
  double radius_deg = 0.265, elevation_deg = 35.0, azimuth_deg = 40.0, exposure = -1.0, cloud_cover = 0.35;
  unsigned seed = 7;
  bool json = false, alpha = false, half = false, quiet = false;
};

// Options that belong to one kind only: using them with another kind is an error, not silently ignored.
void check_options(const CLI::App& app, const std::string& kind) {
  const std::vector<std::pair<std::string, std::set<std::string>>> owners = {
      {"--radiance", {"constant", "sun", "texel", "default"}},
      {"--sky", {"sun"}},
      {"--floor", {"texel"}},
      {"--base", {"gradient"}},
      {"--gain", {"gradient"}},
      {"--form", {"gradient"}},
      {"--radius-deg", {"sun", "default"}},
      {"--elevation-deg", {"sun", "default"}},
      {"--azimuth-deg", {"sun", "default"}},
      {"--direction", {"sun"}},
      {"--texel", {"texel"}},
      {"--cells", {"checker"}},
      {"--color-a", {"checker"}},
      {"--color-b", {"checker"}},
      {"--seed", {"default"}},
      {"--cloud-cover", {"default"}},
  };
  for (const auto& [option, kinds] : owners)
    if (app.count(option) > 0 && kinds.count(kind) == 0) throw Error(option + ": not an option of kind '" + kind + "'");
}

envkit::ParamSpec make_spec(const Args& a) {
  const envkit::Convention& conv = *a.convention;
  const envkit::Kind kind = a.param;
  envkit::ParamSpec spec = envkit::spec_for(kind, 512, conv, a.layout);  // default natural size 512: 1024x512
  if (!a.size.empty()) {
    if (a.size.find_first_of("xX") != std::string::npos) {
      const tools::ImageSize size = tools::parse_image_size("--size", a.size, kMaxSide);
      spec.width = size.width, spec.height = size.height;
    } else {
      const int n = static_cast<int>(tools::parse_integer("--size", a.size, 1, kMaxSide));
      envkit::natural_image_size(kind, n, spec.layout, spec.width, spec.height);
      if (spec.width > kMaxSide || spec.height > kMaxSide)
        throw CLI::ValidationError("--size", "'" + a.size + "': a " + envkit::kind_name(kind) +
                                                 " map of natural size " + a.size + " is " +
                                                 std::to_string(spec.width) + " x " + std::to_string(spec.height) +
                                                 "; width and height must be in [1, " + std::to_string(kMaxSide) + "]");
    }
    // RGBA floats, the rasterizer's copy and the file encoder's: about 48 bytes per texel.
    tools::check_image_size("--size", a.size, std::string(envkit::kind_name(kind)) + " map", spec.width, spec.height,
                            48.0);
  }
  if (!a.grid.empty()) {
    if (a.grid == "centre" || a.grid == "center")
      spec.grid = envkit::TexelGrid::Centre;
    else if (a.grid == "corner")
      spec.grid = envkit::TexelGrid::Corner;
    else
      throw Error("--grid: '" + a.grid + "' must be centre or corner");
  }
  if (!a.basis.empty()) {
    if (a.basis == "envkit" || a.basis == "openexr")
      spec.basis = envkit::CubeBasis::Envkit;
    else if (a.basis == "gl")
      spec.basis = envkit::CubeBasis::GL;
    else
      throw Error("--basis: '" + a.basis + "' must be envkit or gl");
  }
  return spec;
}

std::unique_ptr<probes::Probe> make_probe(const Args& a, const CLI::App& app, const envkit::Parameterization& map,
                                          const probes::RasterOptions& options) {
  auto rgb = [&](const std::string& option, const std::string& value, Vec3 fallback) {
    return value.empty() ? fallback : parse_rgb(option, value);
  };
  const double elevation = probes::radians(a.elevation_deg), azimuth = probes::radians(a.azimuth_deg);
  if (a.kind == "constant") return std::make_unique<probes::ConstantProbe>(rgb("--radiance", a.radiance, Vec3(1.0)));
  if (a.kind == "gradient") {
    probes::GradientProbe::Form form;
    if (a.form == "upper" || a.form == "linear")
      form = probes::GradientProbe::Form::UpperLinear;
    else if (a.form == "quadratic")
      form = probes::GradientProbe::Form::Quadratic;
    else
      throw Error("--form: '" + a.form + "' must be upper or quadratic");
    return std::make_unique<probes::GradientProbe>(
        rgb("--base", a.base, Vec3(0.2, 0.25, 0.3)),
        (a.gain.empty() ? Vec3(0.3, 0.5, 1.0) : parse_rgb("--gain", a.gain, -kMaxRadiance, kMaxRadiance)), form);
  }
  if (a.kind == "sun") {
    Vec3 dir = probes::direction_from_elevation_azimuth(elevation, azimuth);
    if (!a.direction.empty()) {
      if (app.count("--elevation-deg") || app.count("--azimuth-deg"))
        throw Error("--direction: give either a direction or elevation/azimuth, not both");
      dir = parse_rgb("--direction", a.direction, -1e30, 1e30);
      if (!(dir.x != 0.0 || dir.y != 0.0 || dir.z != 0.0)) throw Error("--direction: must not be 0,0,0");
    }
    return std::make_unique<probes::SunProbe>(
        dir, probes::radians(a.radius_deg), rgb("--radiance", a.radiance, Vec3(3e4)), rgb("--sky", a.sky, Vec3(0.05)));
  }
  if (a.kind == "texel") {
    if (a.texel.empty()) throw Error("--texel: required for kind 'texel' (e.g. --texel 10,5)");
    const auto [i, j] = parse_pair("--texel", a.texel, ',', 0, 65535);
    return std::make_unique<probes::TexelProbe>(map, i, j, rgb("--radiance", a.radiance, Vec3(1000.0)),
                                                rgb("--floor", a.floor, Vec3(0.0)));
  }
  if (a.kind == "checker") {
    const auto [nt, np] =
        a.cells.empty() ? std::pair<int, int>{8, 16} : parse_pair("--cells", a.cells, ',', 1, 1 << 20);
    // Every texel integrates the cells its footprint covers: about (n_theta + H)(n_phi + W) cell pieces in all.
    const double pieces = (double(nt) + map.height()) * (double(np) + map.width());
    const double limit = kMaxCheckerPieces + double(map.width()) * map.height();
    if (pieces > limit)
      throw Error("--cells: '" + a.cells + "' on a " + std::to_string(map.width()) + " x " +
                  std::to_string(map.height()) + " map means about " + tools::fmt(pieces, 3) +
                  " cell integrals (limit " + tools::fmt(limit, 3) +
                  "): a texel cannot show that many cells; use fewer cells");
    auto checker = std::make_unique<probes::CheckerProbe>(nt, np, rgb("--color-a", a.color_a, Vec3(0.8)),
                                                          rgb("--color-b", a.color_b, Vec3(0.1)));
    // Without exact integrals every texel an edge crosses is supersampled.
    const double samples = probes::edge_evaluations(*checker, map, options);
    if (samples > kMaxEdgeEvaluations)
      throw Error("--cells: '" + a.cells + "' on a " + std::to_string(map.width()) + " x " +
                  std::to_string(map.height()) + " " + envkit::kind_name(map.kind()) + " map means about " +
                  tools::fmt(samples, 3) + " samples along the cells' edges (limit " +
                  tools::fmt(kMaxEdgeEvaluations, 3) + "): use fewer cells or a smaller map");
    return checker;
  }
  if (a.kind == "default") {
    probes::OutdoorSettings s;
    if (app.count("--elevation-deg")) s.sun_elevation_deg = a.elevation_deg;
    if (app.count("--azimuth-deg")) s.sun_azimuth_deg = a.azimuth_deg;
    if (app.count("--radius-deg")) s.sun_radius_deg = a.radius_deg;
    if (!a.radiance.empty()) s.sun_radiance = parse_rgb("--radiance", a.radiance);
    if (!probes::valid_radiance(s.sun_radiance)) throw Error("--radiance: must be finite and >= 0");
    if (!(s.sun_radius_deg > 0.0 && s.sun_radius_deg <= 90.0)) throw Error("--radius-deg: must be in (0, 90]");
    if (!(a.cloud_cover >= 0.0 && a.cloud_cover <= 1.0)) throw Error("--cloud-cover: must be in [0, 1]");
    s.seed = a.seed;
    s.cloud_cover = a.cloud_cover;
    return std::make_unique<probes::OutdoorProbe>(s);
  }
  throw Error("unknown kind '" + a.kind + "' (expected constant, gradient, sun, texel, checker or default)");
}

int run(const Args& a, const CLI::App& app) {
  check_options(app, a.kind);
  // The preview is a second output: it must not replace the radiance map (or vice versa).
  std::vector<std::string> outputs = envkit::face_paths(a.output);
  if (!a.preview.empty()) outputs.push_back(a.preview);
  envkit::check_outputs(outputs, {}, true);
  const envkit::ParamSpec spec = make_spec(a);
  const std::unique_ptr<envkit::Parameterization> map = envkit::make_parameterization(spec);
  probes::RasterOptions options;
  options.map_to_world = a.convention->frame(spec.kind);
  const std::unique_ptr<probes::Probe> probe = make_probe(a, app, *map, options);

  // Maps with texels that hold no data (mirror ball corners, blank cross cells) get a coverage channel.
  bool uncovered = false;
  for (int j = 0; j < map->height() && !uncovered; ++j)
    for (int i = 0; i < map->width() && !uncovered; ++i) uncovered = !(map->texel_solid_angle(i, j) > 0.0);
  options.alpha = a.alpha || uncovered;
  probes::RasterStats stats;
  envkit::Image image = probes::rasterize(*probe, *map, options, &stats);
  const Vec3 power = probe->total_power();
  const Vec3 map_power = probes::image_power(image, *map);

  // save_envmap writes the same envkit:* metadata as envconvert and, for the openexr convention, the typed
  // OpenEXR envmap attribute that exrenvmap needs.
  envkit::EnvMap env;
  env.image = std::move(image);
  env.param = map->clone();
  env.convention = a.convention->name;
  envkit::SaveOptions so;
  so.write.pixel_type = a.half ? envkit::PixelType::Half : envkit::PixelType::Auto;
  so.write.metadata["envkit:probe"] = probe->describe();
  so.write.metadata["envkit:probe_power"] = rgb_text(power);
  // The map and its preview are one output: both or neither (also on a signal, a full disk or ulimit -f).
  envkit::OutputGroup group;
  const envkit::ClampReport clamped = envkit::save_envmap(a.output, env, so);
  const envkit::Image& image_out = env.image;
  if (!a.preview.empty()) {
    envkit::Image preview = image_out;
    const double scale = std::exp2(a.exposure);
    for (int j = 0; j < preview.height; ++j)
      for (int i = 0; i < preview.width; ++i)
        for (int c = 0; c < preview.channels; ++c)
          if (c != preview.alpha_channel) preview.at(i, j, c) = static_cast<float>(preview.at(i, j, c) * scale);
    envkit::write_image(a.preview, preview);
  }

  // The report is composed before the files are committed: nothing after the commit can fail.
  std::ostringstream report;
  const std::optional<Vec3> irradiance = probe->upward_irradiance();
  if (a.json) {
    nlohmann::json j;
    j["kind"] = a.kind;
    j["probe"] = probe->describe();
    j["parameterization"] = envkit::kind_name(spec.kind);
    j["map"] = map->describe();
    j["width"] = map->width();
    j["height"] = map->height();
    j["output"] = a.output;
    j["total_power"] = rgb_json(power);
    j["power_closed_form"] = probe->power_is_closed_form();
    j["map_power"] = rgb_json(map_power);
    j["upward_irradiance"] = irradiance ? rgb_json(*irradiance) : nlohmann::json();
    nlohmann::json features = nlohmann::json::array();
    for (const probes::FeatureStats& f : stats.features)
      features.push_back({{"solid_angle", f.target},
                          {"sampled", f.sampled},
                          {"scale", f.scale},
                          {"missed", f.missed},
                          {"lost", f.lost}});
    j["features"] = features;
    report << tools::json_text(j) << "\n";
  } else {
    report << "probe: " << probe->describe() << "\n"
           << "map: " << map->describe() << "\n"
           << "total power (" << (probe->power_is_closed_form() ? "closed form" : "numerical")
           << "): " << rgb_text(power) << "\n"
           << "map power (sum L x texel solid angle): " << rgb_text(map_power) << "\n";
    if (irradiance) report << "upward irradiance (+Y plane): " << rgb_text(*irradiance) << "\n";
    report << "wrote " << a.output << (a.preview.empty() ? "" : " and " + a.preview) << "\n";
  }
  group.commit();
  if (clamped.any()) tools::warn(clamped.message(a.output));
  if (!a.json)
    for (const probes::FeatureStats& f : stats.features)
      if (f.lost) std::cerr << "envprobe: warning: a feature lies where the map holds no data; its flux is missing\n";
  if (a.json || !a.quiet) std::cout << report.str();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"envprobe: analytic environments with closed-form power, and the built-in default probe", "envprobe"};
  app.footer(kExamples);
  Args a;
  app.add_option("kind", a.kind, "constant | gradient | sun | texel | checker | default")->required();
  app.add_option("-o,--output", a.output, "output image (.exr float by default; .hdr, .pfm, .tif, .png...)")
      ->required();
  envkit::tools::add_parsed_option(app, "--param", a.param, envkit::parse_kind,
                                   "parameterization: latlong, cube, mirrorball, angular, octahedral, paraboloid")
      ->default_str("latlong");
  app.add_option("--size", a.size, "WxH, or N = natural size (lat-long 2N x N, cube faces N); default 1024x512");
  envkit::tools::add_parsed_option(app, "--convention", a.convention, envkit::tools::convention_named,
                                   envkit::tools::convention_choices())
      ->default_str("envkit");
  app.add_option("--grid", a.grid, "centre | corner (lat-long and cube; default from the convention)");
  envkit::tools::add_parsed_option(app, "--layout", a.layout, envkit::parse_layout,
                                   "cube layout: vstrip, hstrip, hcross, vcross");
  app.add_option("--basis", a.basis, "cube face basis: envkit | gl");
  app.add_option("--radiance", a.radiance, "R or R,G,B: constant L, sun disk Ls, texel value V, default-probe sun");
  app.add_option("--sky", a.sky, "R or R,G,B: uniform sky around the sun (default 0.05)");
  app.add_option("--floor", a.floor, "R or R,G,B: radiance outside the texel (default 0)");
  app.add_option("--base", a.base, "R or R,G,B: gradient base");
  app.add_option("--gain", a.gain, "R or R,G,B: gradient gain");
  app.add_option("--form", a.form, "gradient form: upper (max(y,0)) | quadratic (y^2)")->capture_default_str();
  app.add_option("--radius-deg", a.radius_deg, "sun angular radius, degrees")
      ->check(tools::number_in(0.0, 90.0, true))
      ->capture_default_str();
  app.add_option("--elevation-deg", a.elevation_deg, "sun elevation, degrees")
      ->check(tools::number_in(-90.0, 90.0))
      ->capture_default_str();
  app.add_option("--azimuth-deg", a.azimuth_deg, "sun azimuth, degrees (0 = +Z, 90 = +X)")
      ->check(tools::number_in(-360.0, 360.0))
      ->capture_default_str();
  app.add_option("--direction", a.direction, "x,y,z: sun direction instead of elevation/azimuth");
  app.add_option("--texel", a.texel, "i,j: the lit texel of the output map");
  app.add_option("--cells", a.cells, "n_theta,n_phi: checker cells (default 8,16)");
  app.add_option("--color-a", a.color_a, "R or R,G,B: checker colour of cell (0, 0) (default 0.8)");
  app.add_option("--color-b", a.color_b, "R or R,G,B: the other checker colour (default 0.1)");
  app.add_option("--seed", a.seed, "default probe: cloud seed")
      ->transform(tools::integer_in(0, 4294967295LL))
      ->capture_default_str();
  app.add_option("--cloud-cover", a.cloud_cover, "default probe: cloud cover in [0, 1]")
      ->check(tools::number_in(0.0, 1.0))
      ->capture_default_str();
  app.add_flag("--alpha", a.alpha, "add an alpha (coverage) channel; automatic for maps with empty texels");
  app.add_flag("--half", a.half,
               "write half floats; half cannot hold a sun: values above 65504 are clamped, with a warning");
  app.add_option("--preview", a.preview, "also write a tone-mapped preview (e.g. .png)");
  app.add_option("--exposure", a.exposure, "preview exposure in stops (the sky of the default probe is ~1-1.6)")
      ->check(tools::number_in(-64.0, 64.0))
      ->capture_default_str();
  app.add_flag("--json", a.json, "print the report as JSON");
  app.add_flag("-q,--quiet", a.quiet, "print only warnings and errors (--json still prints its report)");
  return tools::run_cli(app, argc, argv, [&] { return run(a, app); });
}
