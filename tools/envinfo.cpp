// envinfo: describes an environment map: file, pixels, parameterization, power and value statistics.
// Non-finite values are reported, never fatal: the map is read with NaN/Inf replaced by 0 and counted.
#include "common/cli.h"
#include "common/input.h"

#include <envkit/error.h>
#include <envkit/filter.h>
#include <envkit/resample.h>
#include <envkit/solid_angle_table.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

namespace {

namespace tools = envkit::tools;
using nlohmann::json;

const char* kFooter = R"(power: the integral of the radiance over the sphere, per channel
(sum of L x texel solid angle).
mean radiance: power / 4 pi, the radiance of a uniform environment with the same power.
min, max and texel mean are plain statistics over the texels that hold data (not weighted by solid angle).
NaN and Inf values are counted and then read as 0, so a broken file can still be inspected.

Examples:
  envinfo sky.exr
  envinfo probe.hdr --from angular --convention hdrshop
  envinfo 'face_%.png'                       six cube faces
  envinfo sky.exr --json | jq '.statistics[0].power'

Exit status: 0 success; 1 error (one line on stderr); 2 usage error.)";

struct Options {
  tools::InputSpec in;
  bool json = false;
};

struct ChannelStats {
  std::string name;
  double power = 0, mean_radiance = 0, min = 0, max = 0, texel_mean = 0;
};

struct MapStats {
  double solid_angle = 0;  // of the texels with data
  std::vector<ChannelStats> channels;
};

MapStats map_stats(const envkit::EnvMap& map) {
  const envkit::Image& img = map.image;
  const int C = img.channels;
  MapStats s;
  s.solid_angle = envkit::SolidAngleTable(*map.param).total();
  const std::vector<double> power = envkit::total_power(img, *map.param);
  const envkit::TexelSource source(img, *map.param);
  std::vector<double> lo(C, std::numeric_limits<double>::infinity()), hi(C, -lo[0]), sum(C, 0.0);
  std::size_t count = 0;
  for (std::size_t t = 0; t < img.texel_count(); ++t) {
    if (!source.covered(t)) continue;
    ++count;
    const float* px = img.pixels.data() + t * C;
    for (int c = 0; c < C; ++c) {
      lo[c] = std::min(lo[c], double(px[c]));
      hi[c] = std::max(hi[c], double(px[c]));
      sum[c] += px[c];
    }
  }
  for (int c = 0; c < C; ++c)
    s.channels.push_back({img.channel_names[c], power[c], power[c] / envkit::kFourPi, count ? lo[c] : 0.0,
                          count ? hi[c] : 0.0, count ? sum[c] / double(count) : 0.0});
  return s;
}

json stats_json(const envkit::Image& img, const MapStats& s) {
  json channels = json::array();
  for (std::size_t c = 0; c < s.channels.size(); ++c) {
    const ChannelStats& ch = s.channels[c];
    channels.push_back({{"channel", ch.name},
                        {"alpha", int(c) == img.alpha_channel},
                        {"power", ch.power},
                        {"mean_radiance", ch.mean_radiance},
                        {"min", ch.min},
                        {"max", ch.max},
                        {"texel_mean", ch.texel_mean}});
  }
  return channels;
}

void print_text(const tools::LoadedInput& in, const MapStats& s) {
  const envkit::Image& img = in.map.image;
  const envkit::ReadReport& r = in.report;
  auto row = [](const std::string& key, const std::string& value) {
    std::cout << tools::pad(key, 18) << value << "\n";
  };
  row("file", in.path);
  row("image", std::to_string(img.width) + " x " + std::to_string(img.height) + ", " + std::to_string(img.channels) +
                   " channels (" + tools::join(img.channel_names) + ")");
  row("pixels", r.format + " " + r.pixel_type + ", colour space " + r.file_colorspace + " (" + r.colorspace_reason +
                    ")" + (r.converted ? " -> " + r.working_space : ""));
  row("parameterization", in.map.param->describe());
  row("  detected", tools::detection_text(in.detection));
  row("convention", in.map.convention);
  row("solid angle", tools::fmt(s.solid_angle) + " sr (" + tools::fmt(100.0 * s.solid_angle / envkit::kFourPi, 4) +
                         "% of the sphere)");
  row("non-finite", std::to_string(r.nonfinite_count()) + " (" + std::to_string(r.nan_count) + " NaN, " +
                        std::to_string(r.posinf_count) + " +Inf, " + std::to_string(r.neginf_count) + " -Inf)" +
                        (r.nonfinite_count() ? ", read as 0" : ""));
  row("negative", std::to_string(r.negative_count));
  for (const auto& note : r.notes) row("note", note);

  std::cout << "\n" << tools::pad("channel", 10);
  for (const char* h : {"power", "mean radiance", "min", "max", "texel mean"}) std::cout << tools::rpad(h, 15);
  std::cout << "\n";
  for (std::size_t c = 0; c < s.channels.size(); ++c) {
    const ChannelStats& ch = s.channels[c];
    std::cout << tools::pad(ch.name + (int(c) == img.alpha_channel ? " (alpha)" : ""), 10);
    for (double v : {ch.power, ch.mean_radiance, ch.min, ch.max, ch.texel_mean})
      std::cout << tools::rpad(tools::fmt(v), 15);
    std::cout << "\n";
  }
}

// Mode: an environment map. (Table files get their own mode here, chosen by the file's type.)
int describe_envmap(Options& o) {
  o.in.nonfinite = envkit::NonFinitePolicy::Zero;  // report NaN/Inf, don't fail on them
  const tools::LoadedInput in = tools::load_input(o.in);
  const MapStats stats = map_stats(in.map);
  if (o.json) {
    json j = tools::input_json(in);
    j["solid_angle"] = stats.solid_angle;
    j["statistics"] = stats_json(in.map.image, stats);
    std::cout << j.dump(2) << "\n";
  } else {
    print_text(in, stats);
  }
  return tools::kExitOk;
}

int run(Options& o) { return describe_envmap(o); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Describes an environment map: pixels, parameterization, power and statistics per channel.",
               "envinfo");
  Options o;
  app.add_option("IN", o.in.path, "input map (a '%' reads six cube faces)")->required()->type_name("FILE");
  app.add_option("--from", o.in.from, "parameterization: " + tools::kind_choices() + " (default: detected)")
      ->type_name("KIND")
      ->check(tools::kind_validator());
  app.add_option("--layout", o.in.layout, "cube layout: " + tools::layout_choices() + " (default: detected)")
      ->type_name("L")
      ->check(tools::layout_validator());
  app.add_option("--convention", o.in.convention,
                 "convention the map was written for: " + tools::convention_choices() +
                     " (default: from metadata, else envkit)")
      ->type_name("C")
      ->check(tools::convention_validator());
  app.add_flag("--json", o.json, "print one JSON object instead of the table");
  app.footer(kFooter);
  return tools::run_cli(app, argc, argv, [&] { return run(o); });
}
