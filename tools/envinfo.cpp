// envinfo: describes an environment map: file, pixels, parameterization, power and value statistics.
// Non-finite values are reported, never fatal: the map is read with NaN/Inf replaced by 0 and counted.
#include "common/cli.h"
#include "common/input.h"

#include <envkit/distribution_pyramid.h>
#include <envkit/env_tables.h>
#include <envkit/error.h>
#include <envkit/filter.h>
#include <envkit/image_io.h>
#include <envkit/resample.h>
#include <envkit/solid_angle_table.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstring>
#include <fstream>
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

A table file (from envbake) is described instead: grid, importance mode, bake settings, source and its
hash, bytes per table, warnings. --export-exr PREFIX writes what the tables hold as EXR images to look at:
PREFIX_importance.exr (importance per steradian), PREFIX_probability.exr (texel probabilities),
PREFIX_marginal.exr (1 x H row probabilities), PREFIX_conditional.exr (probabilities within each row) and
PREFIX_level<k>.exr for every level of the sum pyramid (node probabilities, level 0 = texels).

Examples:
  envinfo sky.exr
  envinfo sky.envtbl --export-exr out/sky
  envinfo probe.hdr --from angular --convention hdrshop
  envinfo 'face_%.png'                       six cube faces
  envinfo sky.exr --json | jq '.statistics[0].power'

Exit status: 0 success; 1 error (one line on stderr); 2 usage error.)";

struct Options {
  tools::InputSpec in;
  bool json = false;
  std::string export_exr;
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

// ---------------------------------------------------------------------------------------------------------------
// Mode: a table file.

bool is_table_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  char magic[8] = {};
  return f.read(magic, 8) && std::memcmp(magic, "ENVKTBL", 8) == 0;
}

envkit::Image scalar_image(int w, int h, const std::vector<float>& values) {
  envkit::Image image(w, h, 1);
  image.pixels.assign(values.begin(), values.end());
  return image;
}

void export_tables(const envkit::EnvTables& t, const std::string& prefix) {
  const int W = t.width(), H = t.height();
  const std::size_t n = std::size_t(W) * H;
  envkit::WriteOptions wo;
  wo.metadata["envkit:source"] = t.source_path();
  const auto write = [&](const std::string& name, const envkit::Image& image) {
    const std::string path = prefix + "_" + name + ".exr";
    envkit::write_image(path, image, wo);
    tools::info("wrote " + path);
  };
  write("importance", scalar_image(W, H, {t.importance().begin(), t.importance().end()}));

  // Texel probabilities as the stored tables draw them (cdf or pyramid), else the ideal ones.
  const envkit::SphericalDistribution* d = t.distribution(envkit::SamplingMethod::Cdf);
  if (!d) d = t.distribution(envkit::SamplingMethod::Hierarchical);
  std::vector<double> p(n);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      p[std::size_t(y) * W + x] = d ? d->distribution().texel_probability(x, y)
                                    : double(t.importance()[std::size_t(y) * W + x]) *
                                          t.distribution(envkit::SamplingMethod::Alias)->texel_solid_angle(x, y) /
                                          std::max(t.total_importance(), 1e-300);
  std::vector<float> probability(n), marginal(H), conditional(n);
  for (int y = 0; y < H; ++y) {
    double row = 0.0;
    for (int x = 0; x < W; ++x) row += p[std::size_t(y) * W + x];
    marginal[y] = static_cast<float>(row);
    for (int x = 0; x < W; ++x) {
      const std::size_t i = std::size_t(y) * W + x;
      probability[i] = static_cast<float>(p[i]);
      conditional[i] = row > 0.0 ? static_cast<float>(p[i] / row) : 0.0f;
    }
  }
  write("probability", scalar_image(W, H, probability));
  write("marginal", scalar_image(1, H, marginal));
  write("conditional", scalar_image(W, H, conditional));

  if (const envkit::SphericalDistribution* h = t.distribution(envkit::SamplingMethod::Hierarchical)) {
    const auto& pyramid = dynamic_cast<const envkit::PyramidDistribution2D&>(h->distribution());
    const double root = pyramid.node(pyramid.levels(), 0, 0);
    for (int k = 0; k <= pyramid.levels(); ++k) {
      const int lw = pyramid.level_width(k), lh = pyramid.level_height(k);
      std::vector<float> level(std::size_t(lw) * lh);
      for (int j = 0; j < lh; ++j)
        for (int i = 0; i < lw; ++i) level[std::size_t(j) * lw + i] = static_cast<float>(pyramid.node(k, i, j) / root);
      write("level" + std::to_string(k), scalar_image(lw, lh, level));
    }
  }
}

int describe_tables(const Options& o) {
  const envkit::EnvTables t = envkit::EnvTables::load(o.in.path);
  if (o.json) {
    json j = json::parse(t.descriptor());
    j["file"] = o.in.path;
    for (const auto& [name, bytes] : t.table_bytes()) j["bytes"][name] = bytes;
    std::cout << j.dump(2) << "\n";
  } else {
    const auto row = [](const std::string& key, const std::string& value) {
      std::cout << tools::pad(key, 28) << value << "\n";
    };
    const json d = json::parse(t.descriptor());
    row("file", o.in.path + " (envkit sampling tables, format version " + std::to_string(envkit::kTableFormatVersion) + ")");
    row("grid", std::string(envkit::kind_name(t.grid())) + " " + std::to_string(t.width()) + " x " +
                    std::to_string(t.height()));
    row("importance", std::string(envkit::importance_name(t.importance_mode())) +
                          (t.conservative() ? " (conservative)" : "") + ", total " + tools::fmt(t.total_importance()));
    row("source", t.source_path() + " (content hash " + t.source_hash() + ")");
    if (d.contains("bake") && d["bake"].contains("resampled_from"))
      row("resampled from", d["bake"]["resampled_from"].get<std::string>());
    const double texels = double(t.width()) * t.height();
    for (const auto& [name, bytes] : t.table_bytes())
      row("  " + name, tools::fmt(double(bytes) / (1 << 20), 4) + " MiB, " + tools::fmt(double(bytes) / texels, 3) +
                           " bytes/texel");
    for (const std::string& w : t.warnings()) row("warning", w);
  }
  if (!o.export_exr.empty()) export_tables(t, o.export_exr);
  return tools::kExitOk;
}

int run(Options& o) {
  if (!envkit::is_face_pattern(o.in.path) && is_table_file(o.in.path)) return describe_tables(o);
  if (!o.export_exr.empty()) throw CLI::ValidationError("--export-exr", "applies to table files (from envbake) only");
  return describe_envmap(o);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Describes an environment map (pixels, parameterization, power and statistics per channel) or a "
               "table file from envbake.",
               "envinfo");
  Options o;
  app.add_option("IN", o.in.path, "input map (a '%' reads six cube faces) or table file")->required()->type_name("FILE");
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
  app.add_option("--export-exr", o.export_exr, "table files: write importance, marginal, conditionals and pyramid "
                 "levels as PREFIX_*.exr")->type_name("PREFIX");
  app.footer(kFooter);
  return tools::run_cli(app, argc, argv, [&] { return run(o); });
}
