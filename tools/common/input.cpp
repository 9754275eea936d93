#include "common/input.h"

#include <envkit/maps/cubemap.h>

#include "common/cli.h"

namespace envkit::tools {

CLI::Option* add_fix_nonfinite_option(CLI::App& app, InputSpec& spec) {
  return add_parsed_option(app, "--fix-nonfinite", spec.nonfinite, parse_nonfinite_policy,
                           "replace NaN/Inf input values instead of failing")
      ->type_name("zero|clamp");
}

std::vector<std::string> input_paths(const std::string& path) { return face_paths(path); }

LoadedInput load_input(const InputSpec& spec) {
  LoadOptions options;
  options.kind = spec.from;
  options.layout = spec.layout;
  options.convention = spec.convention;
  options.read.colorspace = spec.colorspace;
  options.read.nonfinite = spec.nonfinite;
  options.ball_cx = spec.ball_cx;
  options.ball_cy = spec.ball_cy;
  options.ball_radius = spec.ball_radius;
  options.view = spec.view;
  LoadedInput in;
  in.path = spec.path;
  in.map = load_envmap(spec.path, options, &in.detection, &in.report);
  return in;
}

std::string detection_text(const Detection& d) {
  return d.assumed ? "assumed " + d.reason + "; pass --from to override" : d.reason;
}

void report_input(const LoadedInput& in, bool quiet) {
  const ReadReport& r = in.report;
  // Guesses and surprises in the data are printed even with --quiet: they can make the output wrong.
  if (in.detection.assumed)
    info(in.path + ": assumed " + kind_name(in.detection.kind) + " " + in.detection.reason +
         "; pass --from to override");
  for (const auto& note : r.notes) warn(in.path + ": " + note);
  if (r.negative_count > 0)
    warn(in.path + ": " + std::to_string(r.negative_count) + " negative values (kept as they are)");
  if (quiet) return;
  if (r.replaced_count > 0)
    info(in.path + ": replaced " + std::to_string(r.replaced_count) + " non-finite values (" +
         std::to_string(r.nan_count) + " NaN, " + std::to_string(r.posinf_count) + " +Inf, " +
         std::to_string(r.neginf_count) + " -Inf) (--fix-nonfinite " + nonfinite_policy_name(r.policy) + ")");
  info(in.path + ": " + in.map.param->describe() + "; " + (in.detection.assumed ? "assumed " : "") +
       in.detection.reason + "; convention " + in.map.convention +
       (in.detection.convention_reason.empty() ? "" : " (" + in.detection.convention_reason + ")"));
}

nlohmann::json input_json(const LoadedInput& in) {
  const Image& img = in.map.image;
  const ReadReport& r = in.report;
  nlohmann::json param = {{"kind", kind_name(in.map.param->kind())},
                          {"description", in.map.param->describe()},
                          {"detected", in.detection.reason},
                          {"assumed", in.detection.assumed}};
  if (const std::optional<CubeFaceLayout> cube = in.map.param->cube_faces()) {
    param["layout"] = layout_name(cube->layout);
    param["face_size"] = cube->face_size;
  }
  return {
      {"file", in.path},
      {"width", img.width},
      {"height", img.height},
      {"channels", img.channel_names},
      {"alpha_channel", img.alpha_channel >= 0 ? nlohmann::json(img.alpha_channel) : nlohmann::json()},
      {"format", r.format},
      {"pixel_type", r.pixel_type},
      {"colorspace",
       {{"file", r.file_colorspace},
        {"reason", r.colorspace_reason},
        {"converted", r.converted},
        {"working", r.working_space}}},
      {"parameterization", param},
      {"convention", in.map.convention},
      {"nonfinite",
       {{"nan", r.nan_count},
        {"posinf", r.posinf_count},
        {"neginf", r.neginf_count},
        {"replaced", r.replaced_count},
        {"policy", nonfinite_policy_name(r.policy)}}},
      {"negative", r.negative_count},
      {"notes", r.notes},
      {"summary", r.summary()},
  };
}

}  // namespace envkit::tools
