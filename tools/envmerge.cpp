// envmerge: merges partial captures (fisheye photographs, mirror balls,
// perspective views, maps) into one lat-long, weighting each by its coverage
// and sampling density, with per-capture masks and exposures, and reports the
// solid angle no capture sees. A thin shell over libenv's merge_captures
// (merge.h).
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/envmap/merge.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/view.h>
#include <envkit/maps/view_spec.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "common/cli.h"
#include "common/input.h"

namespace {

namespace fs = std::filesystem;
namespace tools = envkit::tools;

const char* kAtEscape = "an '@' in a file name is written '@@'";

const char* kFooter =
    R"(CAPTURE is FILE or FILE@key=value,key=value,... (each key at most once; an '@' in FILE or in a value is written
'@@': shot@@noon.exr@exposure=2 is the file shot@noon.exr) with keys
  from=KIND            the capture's parameterization (default: its metadata, as every tool detects it)
  lens=L fov=DEG yaw=DEG pitch=DEG roll=DEG
                       a camera view (from=fisheye|perspective): lens, field of view, where it looks (yaw about
                       +Y from +Z towards +X, pitch up), roll; default: the file's envkit:view metadata
  rotate=Y:P:R         rotate the whole capture (degrees, as envconvert --rotate), e.g. a mirror ball shot from
                       the side: rotate=90
  exposure=X           multiply its colour by X (a shot one stop darker: exposure=2)
  mask=FILE            same size as the capture; 0 drops a pixel (camera, photographer, tripod), 1 keeps it
  convention=C         the convention it was written for
Each capture's radiance is its flux-weighted mean over the part of each output texel it sees (what envconvert
gives), weighted by coverage x mask x sampling density (a capture that spends more pixels on a direction counts
more). Alpha is the exact fraction of each texel's solid angle some capture sees (1 on texels seen whole: a
complete map merges to itself), times the largest mask mean there. Directions no capture sees get alpha 0 and
radiance 0; their solid angle is reported.

Examples:
  envmerge front.exr@from=fisheye,lens=equisolid,fov=190 back.exr@from=fisheye,lens=equisolid,fov=190,yaw=180 -o sky.exr
  envmerge ball0.exr@from=mirrorball ball90.exr@from=mirrorball,rotate=90,mask=tripod.png -o sky.exr --size 1024
  envmerge view_*.exr -o sky.exr --json

Exit status: 0 success; 1 error (one line on stderr, no output file written); 2 usage error.)";

struct Options {
  std::vector<std::string> captures;
  std::string out;
  int size = 512, threads = 0;
  bool quiet = false, json = false, force = false;
};

// Numbers inside a capture's key=value list go through the tools' one numeric check (finite, in range).
double number(const std::string& capture, const std::string& key, const std::string& text, double lo, double hi) {
  try {
    return tools::parse_number(key, text, lo, hi);
  } catch (const CLI::ValidationError& e) {
    throw CLI::ValidationError("CAPTURE", "'" + capture + "': " + e.what());
  }
}

struct CaptureSpec {
  tools::InputSpec in;
  double exposure = 1.0;
  std::string mask;
  std::optional<envkit::Mat3> rotation;
};

// A CAPTURE's file name and its key list: the keys start at the first '@' that is not doubled; "@@" is one '@' of
// the name. No key list: nullopt.
std::pair<std::string, std::optional<std::string>> split_capture(const std::string& text) {
  std::string path;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '@') {
      path += text[i];
    } else if (i + 1 < text.size() && text[i + 1] == '@') {
      path += '@';
      ++i;
    } else {
      return {path, text.substr(i + 1)};
    }
  }
  return {path, std::nullopt};
}

// A value of the key list with its "@@" read as '@'; a single '@' is refused (a name written without the escape).
std::string unescape_value(const std::string& capture, const std::string& item) {
  std::string out;
  for (std::size_t i = 0; i < item.size(); ++i) {
    if (item[i] == '@' && (i + 1 >= item.size() || item[i + 1] != '@'))
      throw CLI::ValidationError("CAPTURE", "'" + capture + "': '" + item + "' has a single '@' (" + kAtEscape + ")");
    out += item[i];
    if (item[i] == '@') ++i;
  }
  return out;
}

CaptureSpec parse_capture(const std::string& text) {
  CaptureSpec c;
  const auto [path, keys] = split_capture(text);
  c.in.path = path;
  if (!keys) return c;
  envkit::ViewParams view;
  bool has_view = false;
  double yaw = 0, pitch = 0;
  std::set<std::string> given;
  std::istringstream in(*keys);
  for (std::string item; std::getline(in, item, ',');) {
    const auto eq = item.find('=');
    if (eq == std::string::npos)
      throw CLI::ValidationError("CAPTURE", "'" + text + "': '" + item + "' is not key=value (" + kAtEscape + ")");
    const std::string key = item.substr(0, eq), value = unescape_value(text, item.substr(eq + 1));
    if (!given.insert(key).second)
      throw CLI::ValidationError("CAPTURE", "'" + text + "': key '" + key + "' given twice");
    try {
      if (key == "from")
        c.in.from = envkit::parse_kind(value);
      else if (key == "lens")
        view.lens = envkit::parse_lens(value), has_view = true;
      else if (key == "fov")
        view.fov_degrees = number(text, key, value, 1e-3, 360.0), has_view = true;
      else if (key == "yaw")
        yaw = number(text, key, value, -360.0, 360.0), has_view = true;
      else if (key == "pitch")
        pitch = number(text, key, value, -90.0, 90.0), has_view = true;
      else if (key == "roll")
        view.roll_degrees = number(text, key, value, -360.0, 360.0), has_view = true;
      else if (key == "exposure")
        c.exposure = number(text, key, value, 0.0, 1e30);
      else if (key == "mask")
        c.mask = value;
      else if (key == "convention")
        c.in.convention = &envkit::convention(value);
      else if (key == "rotate") {
        std::string r = value;
        std::replace(r.begin(), r.end(), ':', ',');
        if (r.find(',') == std::string::npos) r += ",0,0";
        c.rotation = envkit::parse_rotation(r);
      } else
        throw CLI::ValidationError(
            "CAPTURE", "'" + text + "': unknown key '" + key + "'" +
                           (key.find('@') != std::string::npos ? std::string(" (") + kAtEscape + ")" : std::string()));
    } catch (const envkit::Error& e) {
      throw CLI::ValidationError("CAPTURE", "'" + text + "': " + e.what());
    }
  }
  if (has_view) {
    view.forward = envkit::direction_from_yaw_pitch(yaw, pitch);
    c.in.view = view;
  }
  if (!(c.exposure > 0.0)) throw CLI::ValidationError("CAPTURE", "'" + text + "': exposure must be positive");
  if (has_view && c.in.from) {  // without from=, the kind (and its check) comes with the file
    try {
      envkit::check_view(*c.in.from, view);
    } catch (const envkit::Error& e) {
      throw CLI::ValidationError("CAPTURE", "'" + text + "': " + e.what());
    }
  }
  return c;
}

int merge(Options& o) {
  // RGBA float output plus the weight and sum buffers of the merge.
  tools::check_image_size("--size", std::to_string(o.size), "merged lat-long", 2LL * o.size, o.size, 40.0);
  std::vector<CaptureSpec> specs;
  for (const std::string& t : o.captures) specs.push_back(parse_capture(t));
  envkit::install_temp_cleanup_on_signal();
  std::vector<std::string> inputs;
  for (const CaptureSpec& s : specs) {
    for (const std::string& p : tools::input_paths(s.in.path)) inputs.push_back(p);
    if (!s.mask.empty()) inputs.push_back(s.mask);
  }
  envkit::check_output_path(o.out, inputs, o.force);
  const auto thread_limit = tools::limit_threads(o.threads);

  // Masks first: a missing or unreadable mask is reported before any capture is loaded and described.
  std::vector<std::optional<envkit::Image>> masks(specs.size());
  for (std::size_t k = 0; k < specs.size(); ++k)
    if (!specs[k].mask.empty()) masks[k] = envkit::read_image(specs[k].mask);
  std::vector<envkit::Capture> captures;
  for (std::size_t k = 0; k < specs.size(); ++k) {
    const CaptureSpec& s = specs[k];
    tools::LoadedInput in = tools::load_input(s.in);
    tools::report_input(in, o.quiet);
    envkit::Capture c;
    c.map = std::move(in.map);
    if (s.rotation) c.map.rotation = *s.rotation;
    c.exposure = s.exposure;
    c.name = s.in.path;
    c.mask = std::move(masks[k]);
    captures.push_back(std::move(c));
  }
  const envkit::LatLongMap dst(2 * o.size, o.size);
  envkit::MergeReport report;
  envkit::EnvMap out;
  out.image = envkit::merge_captures(captures, dst, envkit::identity3(), &report);
  out.param = dst.clone();
  std::erase_if(out.image.metadata, [](const auto& kv) { return kv.first.rfind("envkit:", 0) == 0; });
  envkit::SaveOptions so;
  so.filter = "area";
  so.source = "envmerge of " + std::to_string(captures.size()) + " captures";
  const envkit::ClampReport clamped = envkit::save_envmap(o.out, out, so);
  if (clamped.any()) tools::warn(clamped.message(o.out));

  const double pct = 100.0 * report.uncovered_solid_angle / envkit::kFourPi;
  if (o.json) {
    nlohmann::json j;
    j["output"] = o.out;
    j["uncovered_sr"] = report.uncovered_solid_angle;
    j["uncovered_percent"] = pct;
    for (std::size_t k = 0; k < captures.size(); ++k)
      j["captures"].push_back({{"file", captures[k].name},
                               {"covered_sr", report.covered_solid_angle[k]},
                               {"weight_share", report.weight_share[k]}});
    std::cout << tools::json_text(j) << "\n";
  } else if (!o.quiet) {
    for (std::size_t k = 0; k < captures.size(); ++k) {
      char line[256];
      std::snprintf(line, sizeof line, "%s: sees %.4f sr, carries %.1f%% of the merged weight",
                    captures[k].name.c_str(), report.covered_solid_angle[k], 100.0 * report.weight_share[k]);
      tools::info(line);
    }
    char line[256];
    std::snprintf(line, sizeof line, "wrote %s: %dx%d lat-long; uncovered %.4f sr (%.2f%% of the sphere)",
                  o.out.c_str(), 2 * o.size, o.size, report.uncovered_solid_angle, pct);
    tools::info(line);
  }
  return tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app(
      "Merges partial captures (fisheye photographs, mirror balls, "
      "perspective views, maps) into one\n"
      "lat-long, weighted by coverage and sampling density, with "
      "masks and exposures per capture.",
      "envmerge");
  Options o;
  app.add_option("CAPTURE", o.captures, "captures: FILE or FILE@key=value,... (see below)")
      ->required()
      ->type_name("CAPTURE");
  app.add_option("-o,--output", o.out, "output lat-long map (RGBA: alpha 0 where nothing was seen)")
      ->required()
      ->type_name("OUT");
  app.add_option("--size", o.size, "output size N: 2N x N")
      ->type_name("N")
      ->transform(tools::integer_in(1, 1 << 17))
      ->capture_default_str();
  app.add_flag("--json", o.json, "print the coverage report as JSON on stdout");
  app.add_flag("-f,--force", o.force, "allow OUT to overwrite an input");
  app.add_flag("-q,--quiet", o.quiet, "print only warnings and errors");
  tools::add_threads_option(app, o.threads);
  app.footer(kFooter);
  return tools::run_cli(app, argc, argv, [&] { return merge(o); });
}
