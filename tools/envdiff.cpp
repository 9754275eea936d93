// envdiff: compares two environment maps of any parameterizations and conventions (envkit::compare_maps,
// map_compare.h: B resampled onto A's texels, errors weighted by solid angle) and prints the result.
#include <envkit/core/error.h>
#include <envkit/envmap/map_compare.h>
#include <envkit/resample/filter.h>

#include <cmath>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "common/cli.h"
#include "common/input.h"

namespace {

namespace tools = envkit::tools;
using nlohmann::json;

const char* kFooter = R"(B is resampled onto A's parameterization and orientation with --filter, then
compared over A's texels that hold data (and that B covers), each weighted by its solid angle; colour
channels are compared, alpha is not.
A is the reference R and B the image I:
  rmse    sqrt(mean((I - R)^2))
  relmse  mean((I - R)^2 / (R^2 + 0.01))      (the default metric)
  max     the largest |I - R| (with its texel and direction)
  power   the largest relative difference of total power per channel, |P_B - P_A| / |P_A|, where
          P = integral of L over the sphere, each map on its own texels
A one-channel map is compared with every channel of the other.

Examples:
  envdiff sky.exr sky_cube.exr
  envdiff reference.exr render.exr --metric relmse --fail-above 1e-3
  envdiff sky.exr roundtrip.exr --metric power --fail-above 0.001 --json

Exit status: 0 success (or the metric is within --fail-above); 3 the metric exceeds --fail-above;
1 error (one line on stderr); 2 usage error.)";

struct Options {
  tools::InputSpec a, b;
  envkit::Filter filter = envkit::Filter::Area;
  std::string metric = "relmse";
  std::optional<double> fail_above;
  int threads = 0;
  bool json = false;
};

using Comparison = envkit::MapComparison;

json comparison_json(const Options& o, const tools::LoadedInput& a, const tools::LoadedInput& b, const Comparison& c,
                     double value, bool failed) {
  json power = json::array();
  for (std::size_t k = 0; k < c.channels.size(); ++k)
    power.push_back({{"channel", c.channels[k]},
                     {"a", c.power_a[k]},
                     {"b", c.power_b[k]},
                     {"relative_difference", c.power_rel[k]}});
  json max = {{"value", c.max.value}};
  if (c.max.i >= 0) {
    max["texel"] = {c.max.i, c.max.j};
    max["channel"] = c.channels[c.max.channel];
    max["direction"] = {c.max.direction.x, c.max.direction.y, c.max.direction.z};
  }
  json j = {{"a", tools::input_json(a)},
            {"b", tools::input_json(b)},
            {"filter", envkit::filter_name(o.filter)},
            {"compared_solid_angle", c.compared_solid_angle},
            {"rmse", c.rmse},
            {"relmse", c.relmse},
            {"max_abs_error", max},
            {"power", power},
            {"power_max_relative_difference", c.power_max_rel},
            {"metric", o.metric},
            {"value", value}};
  if (o.fail_above) {
    j["fail_above"] = *o.fail_above;
    j["failed"] = failed;
  }
  return j;
}

void print_text(const Options& o, const tools::LoadedInput& a, const tools::LoadedInput& b, const Comparison& c,
                double value, bool failed) {
  std::cout << "A (reference)  " << a.path << ": " << a.map.param->describe() << ", convention " << a.map.convention
            << "\n";
  std::cout << "B              " << b.path << ": " << b.map.param->describe() << ", convention " << b.map.convention
            << "\n";
  std::cout << "compared       B resampled onto A (filter " << envkit::filter_name(o.filter) << ") over "
            << tools::fmt(c.compared_solid_angle) << " sr\n\n";
  std::cout << tools::pad("rmse", 15) << tools::fmt(c.rmse) << "\n";
  std::cout << tools::pad("relmse", 15) << tools::fmt(c.relmse) << "\n";
  std::cout << tools::pad("max |B - A|", 15) << tools::fmt(c.max.value);
  if (c.max.i >= 0)
    std::cout << " at A texel (" << c.max.i << ", " << c.max.j << ") channel " << c.channels[c.max.channel]
              << ", direction " << tools::vec_text(c.max.direction);
  std::cout << "\n\n"
            << tools::pad("channel", 10) << tools::rpad("power A", 15) << tools::rpad("power B", 15)
            << tools::rpad("rel. diff", 15) << "\n";
  for (std::size_t k = 0; k < c.channels.size(); ++k)
    std::cout << tools::pad(c.channels[k], 10) << tools::rpad(tools::fmt(c.power_a[k]), 15)
              << tools::rpad(tools::fmt(c.power_b[k]), 15) << tools::rpad(tools::fmt(c.power_rel[k], 4), 15) << "\n";
  if (o.fail_above)
    std::cout << "\n"
              << o.metric << " " << tools::fmt(value) << (failed ? " > " : " <= ") << tools::fmt(*o.fail_above) << ": "
              << (failed ? "FAIL" : "ok") << "\n";
}

int diff(Options& o) {
  const auto thread_limit = tools::limit_threads(o.threads);
  const tools::LoadedInput a = tools::load_input(o.a);
  tools::report_input(a, true);
  const tools::LoadedInput b = tools::load_input(o.b);
  tools::report_input(b, true);
  const Comparison c = envkit::compare_maps(a.map, b.map, o.filter, a.path, b.path);
  const double value = envkit::comparison_metric(c, o.metric);
  const bool failed = o.fail_above && !(value <= *o.fail_above);  // NaN fails
  if (o.json)
    std::cout << tools::json_text(comparison_json(o, a, b, c, value, failed)) << "\n";
  else
    print_text(o, a, b, c, value, failed);
  return failed ? tools::kExitThreshold : tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Compares two environment maps of any parameterizations: RMSE, relMSE, max error, power.", "envdiff");
  Options o;
  app.add_option("A", o.a.path, "reference map (a '%' reads six cube faces)")->required()->type_name("FILE");
  app.add_option("B", o.b.path, "map to compare, resampled onto A")->required()->type_name("FILE");
  tools::add_parsed_option(app, "--filter", o.filter, envkit::parse_filter,
                           std::string("filter resampling B onto A: ") + tools::kFilterChoices)
      ->type_name("F")
      ->default_str("area");
  app.add_option("--metric", o.metric, "metric that --fail-above tests")
      ->type_name("M")
      ->check(CLI::IsMember({"rmse", "relmse", "max", "power"}))
      ->capture_default_str();
  app.add_option("--fail-above", o.fail_above, "exit 3 when the metric exceeds X")
      ->type_name("X")
      ->check(tools::number_in(0.0, 1e300));
  tools::add_threads_option(app, o.threads);
  app.add_flag("--json", o.json, "print one JSON object instead of the table");
  app.footer(kFooter);
  return tools::run_cli(app, argc, argv, [&] { return diff(o); });
}
