// envprefilter: real-time image-based lighting from an environment map: a GGX-prefiltered radiance mip chain
// (KTX2, DDS, one mip-mapped OpenEXR cube or one OpenEXR per level), spherical harmonics (JSON), an irradiance map and
// the DFG lookup table. A thin shell over libenv (prefilter.h, sh.h, dfg.h, ibl_files.h); every output is written to
// a temporary file first and all are renamed into place together at the end, so a failure leaves no output at all.
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/ibl/dfg.h>
#include <envkit/ibl/ibl_files.h>
#include <envkit/ibl/ktx2.h>
#include <envkit/ibl/prefilter.h>
#include <envkit/ibl/sh.h>
#include <envkit/io/image_io.h>
#include <envkit/io/request_limits.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "common/cli.h"
#include "common/input.h"
#include "common/progress.h"

namespace {

namespace fs = std::filesystem;
namespace tools = envkit::tools;
using envkit::Kind;

const char* kFooter =
    R"(Outputs (each optional, at least one): -o the GGX radiance mip chain, --sh the spherical harmonics,
--irradiance a diffuse irradiance map, --lut the DFG lookup table. The container follows the extension:
  .ktx2  KTX 2.0, all levels in one file (cube: 6 faces, GL/Vulkan face table), --format picks the texel format
  .dds   DDS with a DX10 header, all levels (cube: DDSCAPS2_CUBEMAP + TEXTURECUBE; same faces as KTX2)
  .exr   OpenEXR, one file: tiled, MIPMAP_LEVELS (ROUND_DOWN), envmap=cube: OpenEXR's own cube (N x 6N strip,
         faces +X -X +Y -Y +Z -Z as ImfEnvmap orients them, corner-sampled), levels past the chain box-filtered
         down to 1 x 1 as OpenEXR requires (envkit:ibl_levels = the prefiltered ones); float channels
  .exr   with '%' in the name: one float file per level ('%' -> 0, 1, ...), GL face table in a vertical strip
  .png/.exr for --lut (PNG: 16-bit, values stored linearly, not sRGB-encoded)
Level m of M has face size max(1, size >> m) and perceptual roughness per --mapping:
  gltf      r = m / (M - 1)                        (glTF-Sample-Viewer; default)
  filament  r = 1 - sqrt(1 - m / (M - 1))          (Filament cmgen: lod = r (2 - r))
  unreal    r = min(1, 2^((1 - (M - 1 - m)) / 1.2)) (UE reflection captures)
and GGX alpha = r^2; level 0 is the area-resampled map. The mapping, roughness and alpha of every level are
written into the file (KTX2 key/value data, EXR attributes). --accuracy trades speed for exactness
(0.2: within 0.5% relative RMS of a brute-force sum over every input texel, no fireflies from a sun).
SH JSON: radiance coefficients, irradiance (cosine lobe A_l convolved) and irradiance/pi, the basis and
windowing written out (see docs/PREFILTER.md).

Examples:
  envprefilter sky.exr -o sky_ggx.ktx2 --sh sky_sh.json --lut dfg.png
      256^2 cube, 9 GGX levels (RGBA16F), order-2 SH, 128 x 128 DFG LUT
  envprefilter sky.hdr -o sky.dds --size 512 --format rg11b10f --mapping filament --levels 6
  envprefilter sky.exr -o sky_ggx.exr --size 128          one tiled mip-mapped OpenEXR cube (exrenvmap's layout)
  envprefilter sky.exr -o 'sky_level%.exr' --size 128     one EXR per level
  envprefilter sky.exr -o sky_octa.ktx2 --octahedral --size 512 --irradiance irr.ktx2
  envprefilter sky.exr --sh sky_sh.json --sh-order 3 --sh-window hanning

Exit status: 0 success; 1 error (one line on stderr, no output file written); 2 usage error.)";

struct Options {
  tools::InputSpec in;
  std::string out, sh, irradiance, lut;
  envkit::RoughnessMapping mapping = envkit::RoughnessMapping::Gltf;
  envkit::GpuFormat format = envkit::GpuFormat::Rgba16f;
  envkit::ShWindow sh_window = envkit::ShWindow::None;
  envkit::DfgLayout lut_layout = envkit::DfgLayout::ScaleBias;
  std::optional<envkit::Mat3> rotation;
  int size = 256, levels = 0, sh_order = 2, irradiance_size = 32, lut_size = 128, threads = 0;
  double accuracy = 0.2;
  bool octahedral = false, force = false, quiet = false, progress = false;
};

void add_options(CLI::App& app, Options& o) {
  app.add_option("IN", o.in.path, "input environment map (any kind envkit reads)")->required()->type_name("FILE");
  app.add_option("-o,--output", o.out,
                 "GGX radiance chain: .ktx2, .dds, .exr (one mip-mapped cube) or .exr with '%' (one file per level)")
      ->type_name("OUT");
  app.add_option("--sh", o.sh, "spherical harmonics JSON")->type_name("FILE.json");
  app.add_option("--irradiance", o.irradiance, "diffuse irradiance map (E/pi): .ktx2, .dds or .exr")->type_name("FILE");
  app.add_option("--lut", o.lut, "DFG lookup table: .png or .exr")->type_name("FILE");
  app.add_option("--size", o.size, "face size (cube) or side (octahedral) of level 0")
      ->transform(tools::integer_in(1, 4096))
      ->capture_default_str();
  app.add_option("--levels", o.levels, "number of levels (default: the full chain to 1 x 1)")
      ->transform(tools::integer_in(0, 15));
  tools::add_parsed_option(app, "--mapping", o.mapping, envkit::parse_roughness_mapping,
                           "roughness of each level: gltf|filament|unreal")
      ->default_str("gltf");
  tools::add_parsed_option(
      app, "--format", o.format, envkit::parse_gpu_format,
      "texel format of .ktx2/.dds outputs: rgba16f|rgba32f|rg11b10f|rgb9e5; only rgba32f holds a sun "
      "(the others clamp above about 65000, and rg11b10f and rgb9e5 store negatives as 0, with a warning)")
      ->default_str("rgba16f");
  app.add_flag("--octahedral", o.octahedral, "equal-area octahedral maps instead of cubes");
  app.add_option("--accuracy", o.accuracy, "quadrature refinement threshold (smaller: slower, more exact)")
      ->check(tools::number_in(0.01, 1.0))
      ->capture_default_str();
  app.add_option("--sh-order", o.sh_order,
                 "SH order L (bands 0..L, (L+1)^2 coefficients: 2 gives 9, the irradiance's; up to " +
                     std::to_string(envkit::kMaxShOrder) + ")")
      ->transform(tools::integer_in(1, envkit::kMaxShOrder))
      ->capture_default_str();
  tools::add_parsed_option(app, "--sh-window", o.sh_window, envkit::parse_sh_window,
                           "SH windowing against ringing: none|hanning|lanczos")
      ->default_str("none");
  app.add_option("--irradiance-size", o.irradiance_size, "face size of the irradiance map (at most 512)")
      ->transform(tools::integer_in(1, 4096))
      ->capture_default_str();
  app.add_option("--lut-size", o.lut_size, "DFG LUT width and height (at most 1024)")
      ->transform(tools::integer_in(1, 4096))
      ->capture_default_str();
  tools::add_parsed_option(app, "--lut-layout", o.lut_layout, envkit::parse_dfg_layout,
                           "DFG channels: scale-bias (R=A, G=B) or filament (R=B, G=A+B)")
      ->default_str("scale-bias");
  tools::add_parsed_option(app, "--from", o.in.from, envkit::parse_kind, "input parameterization (default: detected)")
      ->type_name("KIND");
  tools::add_parsed_option(app, "--from-convention", o.in.convention, tools::convention_named,
                           "convention of the input (default: from metadata, else envkit)")
      ->type_name("C");
  tools::add_parsed_option(app, "--rotate", o.rotation, envkit::parse_rotation,
                           "rotate the environment: yaw,pitch,roll in degrees or 9 matrix entries")
      ->type_name("R");
  tools::add_fix_nonfinite_option(app, o.in);
  tools::add_threads_option(app, o.threads);
  app.add_flag("-f,--force", o.force, "allow an output to overwrite IN");
  app.add_flag("-q,--quiet", o.quiet, "print only warnings and errors");
  app.add_flag("--progress", o.progress, "always show a progress bar");
  app.footer(kFooter);
}

std::string extension(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e;
}

// An .exr chain with '%' in its name: one file per level.
bool per_level_exr(const std::string& path) { return extension(path) == ".exr" && path.find('%') != std::string::npos; }

// Output paths of a chain: one for .ktx2/.dds/.exr, one per level for an .exr with '%'.
std::vector<std::string> chain_paths(const std::string& pattern, int levels) {
  if (!per_level_exr(pattern)) return {pattern};
  std::vector<std::string> paths;
  const std::size_t at = pattern.find('%');
  for (int m = 0; m < levels; ++m) paths.push_back(pattern.substr(0, at) + std::to_string(m) + pattern.substr(at + 1));
  return paths;
}

int full_levels(int size) {
  int n = 1;
  while ((size >> n) >= 1) ++n;
  return n;
}

void check_combinations(const Options& o, bool format_given) {
  if (o.out.empty() && o.sh.empty() && o.irradiance.empty() && o.lut.empty())
    throw CLI::ValidationError("outputs", "nothing to do: give -o, --sh, --irradiance and/or --lut");
  if (!o.out.empty()) {
    const std::string e = extension(o.out);
    if (e != ".ktx2" && e != ".dds" && e != ".exr")
      throw CLI::ValidationError("--output", "'" + o.out + "': expected a .ktx2, .dds or .exr file");
    if (e == ".exr" && !per_level_exr(o.out) && o.octahedral)
      throw CLI::ValidationError("--output",
                                 "one mip-mapped OpenEXR file holds a cube only: put '%' in the name "
                                 "for one octahedral file per level");
  }
  if (o.levels > full_levels(o.size))
    throw CLI::ValidationError("--levels", "a size of " + std::to_string(o.size) + " has at most " +
                                               std::to_string(full_levels(o.size)) + " levels");
  if (!o.irradiance.empty()) {
    const std::string e = extension(o.irradiance);
    if (e != ".ktx2" && e != ".dds" && e != ".exr")
      throw CLI::ValidationError("--irradiance", "'" + o.irradiance + "': expected a .ktx2, .dds or .exr file");
  }
  if (!o.lut.empty() && extension(o.lut) != ".png" && extension(o.lut) != ".exr")
    throw CLI::ValidationError("--lut", "'" + o.lut + "': expected a .png or .exr file");
  if (!o.sh.empty() && extension(o.sh) != ".json")
    throw CLI::ValidationError("--sh", "'" + o.sh + "': expected a .json file");
  const auto gpu_container = [](const std::string& path) {
    return extension(path) == ".ktx2" || extension(path) == ".dds";
  };
  if (format_given && !gpu_container(o.out) && !gpu_container(o.irradiance))
    throw CLI::ValidationError("--format", "applies to .ktx2 and .dds outputs only (OpenEXR outputs hold floats)");
}

/// Refuses, before the input is read, outputs whose size would exhaust memory or take minutes for no visible gain.
void check_sizes(const Options& o) {
  if (!o.out.empty())
    tools::check_request("--size", std::to_string(o.size), [&] { envkit::check_prefilter_size(o.size, o.octahedral); });
  if (!o.irradiance.empty())
    tools::check_request("--irradiance-size", std::to_string(o.irradiance_size),
                         [&] { envkit::check_irradiance_size(o.irradiance_size, o.octahedral); });
  if (!o.lut.empty())
    tools::check_request("--lut-size", std::to_string(o.lut_size), [&] { envkit::check_dfg_lut_size(o.lut_size); });
}

int run(Options& o, bool format_given) {
  check_combinations(o, format_given);
  check_sizes(o);
  envkit::install_temp_cleanup_on_signal();
  const std::vector<std::string> inputs = tools::input_paths(o.in.path);
  const int levels = o.levels == 0 ? full_levels(o.size) : o.levels;
  std::vector<std::string> targets;
  if (!o.out.empty())
    for (const std::string& p : chain_paths(o.out, levels)) targets.push_back(p);
  for (const std::string* p : {&o.sh, &o.irradiance, &o.lut})
    if (!p->empty()) targets.push_back(*p);
  envkit::check_outputs(targets, inputs, o.force);
  const auto thread_limit = tools::limit_threads(o.threads);

  // Every output goes to a temp file next to its target; all are renamed together once everything is written.
  std::vector<std::unique_ptr<envkit::AtomicOutput>> pending;
  auto stage = [&](const std::string& target) -> const std::string& {
    pending.push_back(std::make_unique<envkit::AtomicOutput>(target));
    return pending.back()->temp_path();
  };
  std::vector<std::string> summary;
  std::vector<std::string> clamped;  // warnings of the texel formats, printed once the files exist

  // The DFG LUT depends on no input: it is computed while the input is read and filtered, whose serial stretches
  // (decoding, first touch of big buffers) leave a core idle. Its file is written by this thread, like every other
  // output: the signal cleanup removes staged files between this thread's system calls, and a file another thread
  // renamed into place meanwhile would outlive it.
  std::future<envkit::Image> lut_computed;
  if (!o.lut.empty())
    lut_computed = std::async(std::launch::async, [&o] {
      envkit::DfgOptions d;
      d.width = d.height = o.lut_size;
      d.layout = o.lut_layout;
      return envkit::dfg_lut(d);
    });

  tools::LoadedInput in = tools::load_input(o.in);
  tools::report_input(in, o.quiet);
  if (o.rotation) in.map.rotation = *o.rotation;
  const envkit::MapRef src = in.map.ref();
  const Kind kind = o.octahedral ? Kind::Octahedral : Kind::CubeMap;
  const envkit::GpuFormat format = o.format;

  // Spherical harmonics likewise, beside the GGX levels.
  std::future<envkit::ShCoefficients> sh_projected;
  if (!o.sh.empty())
    sh_projected = std::async(std::launch::async, [&] { return envkit::project_sh(src, o.sh_order, o.sh_window); });

  if (!o.out.empty()) {
    envkit::PrefilterOptions po;
    po.kind = kind;
    po.size = o.size;
    po.levels = levels;
    po.mapping = o.mapping;
    po.accuracy = o.accuracy;
    envkit::set_ibl_cube_faces(o.out, po);
    const std::size_t work = std::size_t(o.size) * o.size * (kind == Kind::CubeMap ? 6 : 1) * 64;
    tools::ProgressBar bar("envprefilter: GGX levels", tools::want_progress(o.progress, o.quiet, work));
    po.progress = bar.callback();
    const envkit::PrefilteredChain chain = envkit::prefilter_ggx(src, po);
    bar.finish();
    for (const envkit::IblFile& f :
         envkit::ggx_chain_files(o.out, chain, kind, fs::path(o.in.path).filename().string()))
      clamped.push_back(envkit::write_ibl_file(stage(f.path), f, kind == Kind::CubeMap, format).message(f.path));
    summary.push_back(o.out + ": " + std::to_string(levels) + " GGX levels, " + envkit::kind_name(kind) + " " +
                      std::to_string(o.size) + ", mapping " + envkit::roughness_mapping_name(o.mapping) +
                      (extension(o.out) == ".exr" ? "" : ", " + envkit::gpu_format_name(o.format)));
  }
  if (!o.sh.empty()) {
    const envkit::ShCoefficients sh = sh_projected.get();
    nlohmann::json j = sh.to_json();
    j["source"] = fs::path(o.in.path).filename().string();
    envkit::AtomicOutput staged(stage(o.sh));  // writes into the staged temp file
    envkit::AtomicOutputStream os(staged);
    os << j.dump(2) << "\n";
    os.close();
    staged.commit();
    summary.push_back(o.sh + ": SH order " + std::to_string(o.sh_order) + ", window " +
                      envkit::sh_window_name(o.sh_window));
  }
  if (!o.irradiance.empty()) {
    envkit::IrradianceOptions io;
    io.kind = kind;
    io.size = o.irradiance_size;
    io.accuracy = o.accuracy;
    const envkit::EnvMap irr = envkit::irradiance_map(src, io);
    const envkit::IblFile f = envkit::irradiance_file(o.irradiance, irr, kind);
    clamped.push_back(envkit::write_ibl_file(stage(f.path), f, kind == Kind::CubeMap, format).message(f.path));
    summary.push_back(o.irradiance + ": irradiance E/pi, " + envkit::kind_name(kind) + " " +
                      std::to_string(o.irradiance_size));
  }
  if (lut_computed.valid()) {
    envkit::WriteOptions w;
    if (extension(o.lut) == ".png") {
      w.pixel_type = envkit::PixelType::UInt16;
      w.encode_colorspace = "raw";  // LUT values are data, not colour
    }
    envkit::write_image(stage(o.lut), lut_computed.get(), w);
    summary.push_back(o.lut + ": DFG LUT " + std::to_string(o.lut_size) + "^2, layout " +
                      envkit::dfg_layout_name(o.lut_layout));
  }
  for (auto& p : pending) p->commit();
  for (const std::string& w : clamped)
    if (!w.empty()) tools::warn(w);
  if (!o.quiet)
    for (const std::string& s : summary) tools::info("wrote " + s);
  return tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app(
      "Prefilters an environment map for real-time image-based lighting: GGX radiance mip chain\n"
      "(KTX2/DDS/EXR), spherical harmonics (JSON), irradiance map and DFG lookup table.",
      "envprefilter");
  Options options;
  add_options(app, options);
  return tools::run_cli(app, argc, argv, [&] { return run(options, app.count("--format") > 0); });
}
