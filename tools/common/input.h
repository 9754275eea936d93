#pragma once
/// @file input.h
/// Reading an environment map the way every tool does: the same detection and the same user-facing lines
/// about what was assumed and what was found in the pixels.
#include <envkit/envmap/envmap.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

namespace envkit::tools {

/// How to read one input; empty strings mean "detect" / "decide from the file".
struct InputSpec {
  std::string path;
  std::optional<Kind> from;                ///< --from: the kind
  std::optional<CubeLayout> layout;        ///< --layout of a cube input
  const Convention* convention = nullptr;  ///< the convention the file was written for
  std::string colorspace;                  ///< ReadOptions::colorspace (canonical_colorspace)
  NonFinitePolicy nonfinite = NonFinitePolicy::Error;
  std::optional<double> ball_cx, ball_cy, ball_radius;
  std::optional<ViewParams> view;  ///< camera views read with --from perspective|fisheye (default: metadata)
};

struct LoadedInput {
  std::string path;
  EnvMap map;
  Detection detection;
  ReadReport report;
};

/// Adds --fix-nonfinite zero|clamp, parsed into `spec.nonfinite`.
CLI::Option* add_fix_nonfinite_option(CLI::App& app, InputSpec& spec);

/// Every path the input names (six face files for a '%' pattern), for check_output_path.
std::vector<std::string> input_paths(const std::string& path);

/// Reads and detects (load_envmap); throws envkit::Error with one line naming the file.
LoadedInput load_input(const InputSpec& spec);

/// Tells the user what the tool assumed and found, on stderr:
///  - "<path>: assumed <kind> <reason>; pass --from to override" when the kind was guessed (always);
///  - read notes, negative values and replaced non-finite values as warnings (always);
///  - "<path>: <description> (<how it was detected>), convention <c>" unless `quiet`.
void report_input(const LoadedInput& input, bool quiet);

/// How the parameterization was decided ("from its envkit:parameterization metadata"; "assumed from the 2:1
/// aspect ratio; pass --from to override").
std::string detection_text(const Detection& detection);

/// The same facts as JSON (file, size, channels, parameterization, convention, read report).
nlohmann::json input_json(const LoadedInput& input);

}  // namespace envkit::tools
