// envdiff: compares two environment maps of any parameterizations and conventions. B is resampled onto A's
// texels (A's parameterization and orientation), then errors are averaged over A's texels weighted by solid
// angle, so the numbers measure the environments, not their layouts.
#include "common/cli.h"
#include "common/input.h"

#include <envkit/error.h>
#include <envkit/filter.h>
#include <envkit/resample.h>
#include <envkit/solid_angle_table.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <iostream>
#include <limits>
#include <optional>
#include <string>
#include <vector>

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
  std::string filter = "area", metric = "relmse";
  std::optional<double> fail_above;
  int threads = 0;
  bool json = false;
};

struct MaxError {
  double value = 0;
  int i = -1, j = -1, channel = -1;
  envkit::Vec3 direction;
};

struct Comparison {
  double rmse = 0, relmse = 0, compared_solid_angle = 0;
  MaxError max;
  std::vector<std::string> channels;
  std::vector<double> power_a, power_b, power_rel;
  double power_max_rel = 0;
};

// Colour channels of a map; a single channel is broadcast against the other map's channels.
std::vector<int> colour_channels(const envkit::Image& img) {
  std::vector<int> cs;
  for (int c = 0; c < img.channels; ++c)
    if (c != img.alpha_channel) cs.push_back(c);
  return cs;
}

double relative_difference(double a, double b) {
  if (a == b) return 0.0;
  return a == 0.0 ? std::numeric_limits<double>::infinity() : std::abs(b - a) / std::abs(a);
}

Comparison compare(const tools::LoadedInput& a, const tools::LoadedInput& b, envkit::Filter filter) {
  const envkit::EnvMap& A = a.map;
  envkit::ResampleOptions ro;
  ro.filter = filter;
  const envkit::Image R = envkit::resample(b.map.ref(), *A.param, A.to_world(), ro);
  const std::vector<int> ca = colour_channels(A.image), cb = colour_channels(R);
  if (ca.size() != cb.size() && ca.size() != 1 && cb.size() != 1)
    envkit::fail(b.path, std::to_string(cb.size()) + " colour channels cannot be compared with the " +
                             std::to_string(ca.size()) + " of " + a.path);
  const std::size_t n = std::max(ca.size(), cb.size());
  // Where B has no data (a coverage channel the resampling added), the texel is not compared.
  const int coverage = b.map.image.alpha_channel < 0 ? R.alpha_channel : -1;

  Comparison cmp;
  for (std::size_t k = 0; k < n; ++k)
    cmp.channels.push_back(ca.size() == n ? A.image.channel_names[ca[k]] : R.channel_names[cb[k]]);
  const envkit::SolidAngleTable omega(*A.param);
  double se = 0, rel = 0, weight = 0;
  for (int j = 0; j < A.image.height; ++j) {
    for (int i = 0; i < A.image.width; ++i) {
      double w = omega(i, j);
      if (coverage >= 0) w *= R.at(i, j, coverage);
      if (w <= 0.0) continue;
      weight += w;
      for (std::size_t k = 0; k < n; ++k) {
        const double ref = A.image.at(i, j, ca[std::min(k, ca.size() - 1)]);
        const double img = R.at(i, j, cb[std::min(k, cb.size() - 1)]);
        const double d = img - ref;
        se += w * d * d;
        rel += w * d * d / (ref * ref + 1e-2);
        if (std::abs(d) > cmp.max.value) cmp.max = {std::abs(d), i, j, int(k), {}};
      }
    }
  }
  if (weight > 0.0) {
    cmp.rmse = std::sqrt(se / (weight * double(n)));
    cmp.relmse = rel / (weight * double(n));
  }
  cmp.compared_solid_angle = weight;
  if (cmp.max.i >= 0) {
    envkit::Vec3 d;
    A.param->to_direction(envkit::Vec2(cmp.max.i + 0.5, cmp.max.j + 0.5), d);
    cmp.max.direction = envkit::apply(A.to_world(), d);
  }

  // Power of each map on its own texels: resampling does not enter the flux comparison.
  const std::vector<double> pa = envkit::total_power(A.image, *A.param);
  const std::vector<double> pb = envkit::total_power(b.map.image, *b.map.param);
  const std::vector<int> cb_own = colour_channels(b.map.image);
  for (std::size_t k = 0; k < n; ++k) {
    cmp.power_a.push_back(pa[ca[std::min(k, ca.size() - 1)]]);
    cmp.power_b.push_back(pb[cb_own[std::min(k, cb_own.size() - 1)]]);
    cmp.power_rel.push_back(relative_difference(cmp.power_a.back(), cmp.power_b.back()));
    cmp.power_max_rel = std::max(cmp.power_max_rel, cmp.power_rel.back());
  }
  return cmp;
}

double metric_value(const Comparison& c, const std::string& metric) {
  if (metric == "rmse") return c.rmse;
  if (metric == "max") return c.max.value;
  if (metric == "power") return c.power_max_rel;
  return c.relmse;
}

json comparison_json(const Options& o, const tools::LoadedInput& a, const tools::LoadedInput& b, const Comparison& c,
                     double value, bool failed) {
  json power = json::array();
  for (std::size_t k = 0; k < c.channels.size(); ++k)
    power.push_back({{"channel", c.channels[k]}, {"a", c.power_a[k]}, {"b", c.power_b[k]},
                     {"relative_difference", c.power_rel[k]}});
  json max = {{"value", c.max.value}};
  if (c.max.i >= 0) {
    max["texel"] = {c.max.i, c.max.j};
    max["channel"] = c.channels[c.max.channel];
    max["direction"] = {c.max.direction.x, c.max.direction.y, c.max.direction.z};
  }
  json j = {{"a", tools::input_json(a)},
            {"b", tools::input_json(b)},
            {"filter", o.filter},
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
  std::cout << "compared       B resampled onto A (filter " << o.filter << ") over "
            << tools::fmt(c.compared_solid_angle) << " sr\n\n";
  std::cout << tools::pad("rmse", 15) << tools::fmt(c.rmse) << "\n";
  std::cout << tools::pad("relmse", 15) << tools::fmt(c.relmse) << "\n";
  std::cout << tools::pad("max |B - A|", 15) << tools::fmt(c.max.value);
  if (c.max.i >= 0)
    std::cout << " at A texel (" << c.max.i << ", " << c.max.j << ") channel " << c.channels[c.max.channel]
              << ", direction " << tools::vec_text(c.max.direction);
  std::cout << "\n\n" << tools::pad("channel", 10) << tools::rpad("power A", 15) << tools::rpad("power B", 15)
            << tools::rpad("rel. diff", 15) << "\n";
  for (std::size_t k = 0; k < c.channels.size(); ++k)
    std::cout << tools::pad(c.channels[k], 10) << tools::rpad(tools::fmt(c.power_a[k]), 15)
              << tools::rpad(tools::fmt(c.power_b[k]), 15) << tools::rpad(tools::fmt(c.power_rel[k], 4), 15) << "\n";
  if (o.fail_above)
    std::cout << "\n" << o.metric << " " << tools::fmt(value) << (failed ? " > " : " <= ") << tools::fmt(*o.fail_above)
              << ": " << (failed ? "FAIL" : "ok") << "\n";
}

int diff(Options& o) {
  const auto thread_limit = tools::limit_threads(o.threads);
  const tools::LoadedInput a = tools::load_input(o.a);
  tools::report_input(a, true);
  const tools::LoadedInput b = tools::load_input(o.b);
  tools::report_input(b, true);
  const Comparison c = compare(a, b, envkit::parse_filter(o.filter));
  const double value = metric_value(c, o.metric);
  const bool failed = o.fail_above && !(value <= *o.fail_above);  // NaN fails
  if (o.json) std::cout << comparison_json(o, a, b, c, value, failed).dump(2) << "\n";
  else print_text(o, a, b, c, value, failed);
  return failed ? tools::kExitThreshold : tools::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Compares two environment maps of any parameterizations: RMSE, relMSE, max error, power.", "envdiff");
  Options o;
  app.add_option("A", o.a.path, "reference map (a '%' reads six cube faces)")->required()->type_name("FILE");
  app.add_option("B", o.b.path, "map to compare, resampled onto A")->required()->type_name("FILE");
  app.add_option("--filter", o.filter, std::string("filter resampling B onto A: ") + tools::kFilterChoices)
      ->type_name("F")
      ->check(tools::filter_validator())
      ->capture_default_str();
  app.add_option("--metric", o.metric, "metric that --fail-above tests")
      ->type_name("M")
      ->check(CLI::IsMember({"rmse", "relmse", "max", "power"}))
      ->capture_default_str();
  app.add_option("--fail-above", o.fail_above, "exit 3 when the metric exceeds X")
      ->type_name("X")
      ->check(CLI::NonNegativeNumber);
  tools::add_threads_option(app, o.threads);
  app.add_flag("--json", o.json, "print one JSON object instead of the table");
  app.footer(kFooter);
  return tools::run_cli(app, argc, argv, [&] { return diff(o); });
}
