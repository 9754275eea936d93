// envbake: bakes importance-sampling tables (cdf, alias, hierarchical, MIS-compensated) of an environment map
// into a versioned table file that envsample, envinfo and envrender load.
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/io/color.h>
#include <envkit/tables/env_tables.h>

#include <chrono>
#include <iostream>
#include <sstream>
#include <string>

#include "common/cli.h"
#include "common/input.h"
#include "common/progress.h"

namespace {

namespace tools = envkit::tools;
using envkit::Kind;

// The widest bake grid (a lat-long of --size 65536): no importance map is wider.
constexpr int kMaxImportanceSide = 1 << 17;

const char* kFooter = R"(What is baked: importance = luminance (the working space's weights, Rec.709 primaries
by default), average or max of the colour channels, times the exact solid angle of each texel. Maps that
are not an envkit lat-long (or octahedral with --param octahedral, HEALPix with --param healpix) are first
resampled onto one with the flux-conserving area filter, applying their convention and rotation: the
tables live in world directions.
--param healpix: tables on the HEALPix image grid itself (4 N_side x 3 N_side, twelve base pixels, every
  texel one equal-area HEALPix pixel): a HEALPix map is baked without resampling. envrender's product
  strategies need a latlong or octahedral table.
--size N: bake grid N (lat-long 2N x N, octahedral N x N, healpix N_side = N: 4N x 3N); default: the
  input's grid, or as many texels.
--resolution WxH: bake the importance at a lower resolution (area-filtered): smaller, faster tables,
  less exact importance (a speed/memory vs accuracy knob; rendering stays unbiased). Octahedral: WxW;
  healpix: 4M x 3M.
--conservative: each texel's importance is the max over its 3x3 neighbourhood, so radiance looked up
  with a bilinear filter is never non-zero where the pdf is zero.
--tables: any of cdf, alias, hierarchical, compensated, sun. compensated adds the MIS-compensated
  twin max(f - mean, 0) (Karlik et al. 2019) of every other requested table. sun looks for the map's sun
  and stores the sun split of every table (the sun's texels and the rest of the map's table), which
  envrender then loads instead of building at every start (about 1.7 s at 8192x4096, for 171 MiB more
  file). Default: hierarchical, the
  table envrender, envsample and the Python module sample by default (at 8192x4096: 299 MiB; with cdf and
  alias 939 MiB). Importance at the full resolution by default: coarser was less efficient to render
  on every map measured (BENCHMARKS.md, "Bake sizing").
The file records the source's content hash: envrender refuses tables whose source image changed.

Examples:
  envbake sky.exr -o sky.envtbl
  envbake sky.exr -o sky_all.envtbl --tables cdf,alias,hierarchical
  envbake sky.exr -o sky.envtbl --tables hierarchical,sun      what envrender's default strategy reads
  envbake sky.exr -o sky_small.envtbl --resolution 512x256
  envbake sky.exr -o sky.envtbl --tables cdf,alias,hierarchical,compensated --importance max
  envbake cube.exr -o cube.envtbl --param octahedral --size 1024
  envbake hp.exr -o hp.envtbl --param healpix

Exit status: 0 success; 1 error (one line on stderr, no output file written); 2 usage error.)";

struct Options {
  tools::InputSpec in;
  std::string out, resolution, tables = "hierarchical";
  envkit::ImportanceMode importance = envkit::ImportanceMode::Luminance;
  Kind grid = Kind::LatLong;
  int size = 0, threads = 0;
  bool conservative = false, force = false, quiet = false, progress = false, json = false;
};

// The kinds a table file's grid can be.
Kind bake_grid(const std::string& name) {
  const Kind kind = envkit::parse_kind(name);
  if (kind != Kind::LatLong && kind != Kind::Octahedral && kind != Kind::HEALPix)
    throw envkit::Error("'" + name + "' is no bake grid (use latlong, octahedral or healpix)");
  return kind;
}

void parse_tables(const std::string& list, envkit::BakeOptions& b) {
  std::vector<std::string> names;
  std::stringstream ss(list);
  for (std::string item; std::getline(ss, item, ',');) names.push_back(item);
  try {
    envkit::select_tables(names, b);
  } catch (const envkit::Error& e) {
    throw CLI::ValidationError("--tables", e.what());
  }
}

void parse_resolution(const std::string& text, envkit::BakeOptions& b) {
  const tools::ImageSize size = tools::parse_image_size("--resolution", text, kMaxImportanceSide);
  tools::check_image_size("--resolution", text, "an importance map", size.width, size.height, 40.0);
  b.importance_width = size.width;
  b.importance_height = size.height;
}

int run(Options& o) {
  envkit::BakeOptions b;
  b.importance = o.importance;
  b.grid = o.grid;
  b.conservative = o.conservative;
  parse_tables(o.tables, b);
  if (!o.resolution.empty()) parse_resolution(o.resolution, b);
  if (o.size > 0) {
    b.height = b.grid == Kind::HEALPix ? 3 * o.size : o.size;
    b.width = b.grid == Kind::LatLong ? 2 * o.size : b.grid == Kind::HEALPix ? 4 * o.size : o.size;
    // Importance, cdf, alias and hierarchical tables: about 40 bytes per texel while baking.
    tools::check_image_size("--size", std::to_string(o.size), "a bake grid", b.width, b.height, 40.0);
  }
  if (b.grid == Kind::Octahedral && b.importance_width != b.importance_height)
    throw CLI::ValidationError("--resolution", "an octahedral importance map is square (WxW)");
  if (b.grid == Kind::HEALPix && (b.importance_width % 4 != 0 || b.importance_width * 3 != b.importance_height * 4))
    throw CLI::ValidationError("--resolution",
                               "a HEALPix importance map is 4M x 3M (M = its N_side), not " + o.resolution);

  const std::vector<std::string> inputs = tools::input_paths(o.in.path);
  envkit::check_output_path(o.out, inputs, o.force);
  envkit::install_temp_cleanup_on_signal();
  const auto limit = tools::limit_threads(o.threads);

  const auto start = std::chrono::steady_clock::now();
  const tools::LoadedInput in = tools::load_input(o.in);
  tools::report_input(in, o.quiet);
  const std::string hash = envkit::file_content_hash(inputs);

  tools::ProgressBar bar("baking", tools::want_progress(o.progress, o.quiet, in.map.image.texel_count()));
  b.progress = [&bar](double f, const char*) { bar.update(f); };
  const envkit::EnvTables t = envkit::EnvTables::bake(in.map, b, o.in.path, hash);
  bar.finish();
  t.save(o.out);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  for (const envkit::TableWarning& w : t.warnings()) tools::warn(o.in.path + ": " + w.message);
  if (o.json) {
    nlohmann::json j = nlohmann::json::parse(t.descriptor());
    j["output"] = o.out;
    j["seconds"] = seconds;
    for (const auto& [name, bytes] : t.table_bytes()) j["bytes"][name] = bytes;
    std::cout << tools::json_text(j) << "\n";
  } else if (!o.quiet) {
    std::cout << o.out << ": " << envkit::kind_name(t.grid()) << " " << t.width() << " x " << t.height() << ", "
              << envkit::importance_name(t.importance_mode()) << " importance"
              << (t.conservative() ? " (conservative)" : "") << ", total " << tools::fmt(t.total_importance()) << "\n";
    const double texels = double(t.width()) * t.height();
    for (const auto& [name, bytes] : t.table_bytes())
      std::cout << "  " << tools::pad(name, 24) << tools::rpad(tools::fmt(double(bytes) / (1 << 20), 4), 10) << " MiB  "
                << tools::fmt(double(bytes) / texels, 3) << " bytes/texel\n";
    std::cout << "  baked in " << tools::fmt(seconds, 3) << " s\n";
  }
  return tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Bakes importance-sampling tables of an environment map into a table file.", "envbake");
  Options o;
  app.add_option("IN", o.in.path, "input map (a '%' reads six cube faces)")->required()->type_name("FILE");
  app.add_option("-o,--output", o.out, "output table file (.envtbl)")->required()->type_name("TABLES");
  tools::add_parsed_option(app, "--importance", o.importance, envkit::parse_importance,
                           "scalar importance of a texel: luminance, average or max")
      ->type_name("MODE")
      ->default_str("luminance");
  tools::add_parsed_option(app, "--param", o.grid, bake_grid, "bake grid: latlong, octahedral or healpix")
      ->type_name("KIND")
      ->default_str("latlong");
  app.add_option("--size", o.size, "bake grid size N (latlong 2N x N, octahedral N x N, healpix 4N x 3N)")
      ->type_name("N")
      ->transform(tools::integer_in(1, 1 << 16));
  app.add_option("--resolution", o.resolution, "importance resolution (area-filtered down), e.g. 1024x512")
      ->type_name("WxH");
  app.add_option("--tables", o.tables, "tables to bake: cdf,alias,hierarchical,compensated,sun")
      ->type_name("LIST")
      ->capture_default_str();
  app.add_flag("--conservative", o.conservative, "importance = max over each texel's bilinear footprint");
  tools::add_parsed_option(app, "--from", o.in.from, envkit::parse_kind, "input parameterization (default: detected)")
      ->type_name("KIND");
  tools::add_parsed_option(app, "--layout", o.in.layout, envkit::parse_layout,
                           "cube layout of the input (default: detected)")
      ->type_name("L");
  tools::add_parsed_option(app, "--from-convention", o.in.convention, tools::convention_named,
                           "convention of the input (default: from metadata)")
      ->type_name("C");
  tools::add_parsed_option(app, "--colorspace", o.in.colorspace, envkit::canonical_colorspace,
                           "colour space of the input pixels (default: from the file)")
      ->type_name("CS");
  tools::add_fix_nonfinite_option(app, o.in);
  tools::add_threads_option(app, o.threads);
  app.add_flag("-f,--force", o.force, "allow TABLES to overwrite an input");
  app.add_flag("-q,--quiet", o.quiet, "print only warnings and errors");
  app.add_flag("--progress", o.progress, "always show a progress bar");
  app.add_flag("--json", o.json, "print the table description as JSON");
  app.footer(kFooter);
  return tools::run_cli(app, argc, argv, [&] { return run(o); });
}
