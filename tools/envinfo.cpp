// envinfo: describes an environment map: file, pixels, parameterization, power and value statistics.
// Non-finite values are reported, never fatal: the map is read with NaN/Inf replaced by 0 and counted.
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/envmap/map_stats.h>
#include <envkit/envmap/sun.h>
#include <envkit/ibl/exr_cube_mips.h>
#include <envkit/ibl/ktx2.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/filter.h>
#include <envkit/resample/resample.h>
#include <envkit/sampling/distribution_hierarchical.h>
#include <envkit/tables/env_tables.h>
#include <envkit/tables/sun_split.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/cli.h"
#include "common/input.h"

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
PREFIX_level<k>.exr for every level of the hierarchical table (node probabilities, level 0 = texels).

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

using envkit::ChannelStats;
using envkit::MapStats;

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

// A multi-level OpenEXR file (envprefilter's mip-mapped cube): its levels and the GGX chain's attributes, since the
// statistics below describe level 0 only.
std::optional<envkit::ExrLevels> exr_levels(const tools::LoadedInput& in) {
  if (in.report.format != "openexr" || envkit::is_face_pattern(in.path)) return std::nullopt;
  std::optional<envkit::ExrLevels> levels = envkit::read_exr_levels(in.path);
  if (levels && levels->sizes.size() < 2) return std::nullopt;
  return levels;
}

// The sun as envinfo reports it: direction as elevation above the horizon and azimuth (0 = +Z, 90 = +X, the
// convention of envprobe's --azimuth-deg), in degrees.
double elevation_deg(const envkit::Vec3& d) { return std::asin(std::clamp(d.y, -1.0, 1.0)) * 180.0 / envkit::kPi; }
double azimuth_deg(const envkit::Vec3& d) { return std::atan2(d.x, d.z) * 180.0 / envkit::kPi; }

json sun_json(const std::optional<envkit::SunEstimate>& sun) {
  if (!sun) return nullptr;
  return {{"direction", {sun->direction.x, sun->direction.y, sun->direction.z}},
          {"elevation_deg", elevation_deg(sun->direction)},
          {"azimuth_deg", azimuth_deg(sun->direction)},
          {"angular_radius_deg", sun->angular_radius * 180.0 / envkit::kPi},
          {"solid_angle", sun->solid_angle},
          {"texels", sun->texels},
          {"radiance", sun->radiance},
          {"power", sun->power},
          {"power_share", sun->power_share},
          {"clipped", sun->clipped},
          {"clipped_texels", sun->clipped_texels}};
}

std::string sun_text(const std::optional<envkit::SunEstimate>& sun) {
  if (!sun) return "none (no small region outshines the map and carries >= 1% of its light)";
  return "elevation " + tools::fmt(elevation_deg(sun->direction), 4) + " deg, azimuth " +
         tools::fmt(azimuth_deg(sun->direction), 4) + " deg (0 = +Z, 90 = +X), radius " +
         tools::fmt(sun->angular_radius * 180.0 / envkit::kPi, 3) + " deg (" + std::to_string(sun->texels) +
         " texels), radiance " + tools::fmt(sun->radiance[0], 4) + ", " + tools::fmt(sun->radiance[1], 4) + ", " +
         tools::fmt(sun->radiance[2], 4) + ", " + tools::fmt(100.0 * sun->power_share, 3) + "% of the light";
}

void warn_if_clipped(const tools::LoadedInput& in, const std::optional<envkit::SunEstimate>& sun) {
  if (sun && sun->clipped)
    tools::warn(in.path + ": the sun is clipped flat (" + std::to_string(sun->clipped_texels) + " of its " +
                std::to_string(sun->texels) +
                " texels share its maximum value): the map holds too little of its power");
}

std::string meta(const envkit::Image& img, const std::string& key) {
  const auto it = img.metadata.find(key);
  return it == img.metadata.end() ? "" : it->second;
}

void print_text(const tools::LoadedInput& in, const MapStats& s, const std::optional<envkit::SunEstimate>& sun) {
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
  row("sun", sun_text(sun));
  for (const auto& note : r.notes) row("note", note);
  if (const auto levels = exr_levels(in)) {
    std::string sizes;
    for (const auto& [w, h] : levels->sizes)
      sizes += (sizes.empty() ? "" : " ") + std::to_string(w) + "x" + std::to_string(h);
    row("levels", std::to_string(levels->sizes.size()) + " (" + levels->mode + ", rounding " + levels->rounding +
                      "): " + sizes + "; statistics of level 0");
    if (!meta(img, "envkit:ibl_levels").empty())
      row("GGX chain", meta(img, "envkit:ibl_levels") + " prefiltered levels, mapping " +
                           meta(img, "envkit:ibl_roughness_mapping") + ", roughness " +
                           meta(img, "envkit:ibl_roughness"));
  }

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
  const MapStats stats = envkit::map_statistics(in.map);
  const std::optional<envkit::SunEstimate> sun = envkit::detect_sun(in.map);
  warn_if_clipped(in, sun);
  if (o.json) {
    json j = tools::input_json(in);
    j["solid_angle"] = stats.solid_angle;
    j["statistics"] = stats_json(in.map.image, stats);
    j["sun"] = sun_json(sun);
    if (const auto levels = exr_levels(in)) {
      j["levels"] = {{"mode", levels->mode}, {"rounding", levels->rounding}, {"sizes", levels->sizes}};
      if (!meta(in.map.image, "envkit:ibl_levels").empty())
        j["ggx_chain"] = {{"prefiltered_levels", meta(in.map.image, "envkit:ibl_levels")},
                          {"mapping", meta(in.map.image, "envkit:ibl_roughness_mapping")},
                          {"roughness", meta(in.map.image, "envkit:ibl_roughness")}};
    }
    std::cout << tools::json_text(j) << "\n";
  } else {
    print_text(in, stats, sun);
  }
  return tools::kExitOk;
}

// ---------------------------------------------------------------------------------------------------------------
// Mode: a table file.

bool is_table_file(const std::string& path) {
  if (std::error_code ec; !std::filesystem::is_regular_file(path, ec)) return false;  // a FIFO would block here
  std::ifstream f(path, std::ios::binary);
  char magic[8] = {};
  return f.read(magic, 8) && std::memcmp(magic, "ENVKTBL", 8) == 0;
}

envkit::Image scalar_image(int w, int h, const std::vector<float>& values) {
  envkit::Image image(w, h, 1);
  image.pixels.assign(values.begin(), values.end());
  return image;
}

void export_tables(const envkit::EnvTables& t, const std::string& table_path, const std::string& prefix) {
  const int W = t.width(), H = t.height();
  const std::size_t n = std::size_t(W) * H;
  envkit::WriteOptions wo;
  wo.metadata["envkit:source"] = t.source_path();
  // Every image or none: the set is committed at the end as one group (also on a signal, a full disk, ulimit -f).
  envkit::OutputGroup group;
  std::vector<std::string> written;
  const auto write = [&](const std::string& name, const envkit::Image& image) {
    const std::string path = prefix + "_" + name + ".exr";
    // Checked as each name is made (the names depend on the tables): a failure here commits nothing.
    written.push_back(path);
    envkit::check_outputs(written, {table_path}, false);
    envkit::write_image(path, image, wo);
  };
  write("importance", scalar_image(W, H, {t.importance().begin(), t.importance().end()}));

  // Texel probabilities as the stored tables draw them (cdf or hierarchical), else the ideal ones.
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

  const envkit::SphericalDistribution* h = t.distribution(envkit::SamplingMethod::Hierarchical);
  if (h && h->distribution().builtin() == envkit::BuiltinDistribution::Hierarchical) {
    const auto& tree = static_cast<const envkit::HierarchicalDistribution2D&>(h->distribution());
    const double root = tree.node(tree.levels(), 0, 0);
    for (int k = 0; k <= tree.levels(); ++k) {
      const int lw = tree.level_width(k), lh = tree.level_height(k);
      std::vector<float> level(std::size_t(lw) * lh);
      for (int j = 0; j < lh; ++j)
        for (int i = 0; i < lw; ++i) level[std::size_t(j) * lw + i] = static_cast<float>(tree.node(k, i, j) / root);
      write("level" + std::to_string(k), scalar_image(lw, lh, level));
    }
  }
  group.commit();
  for (const std::string& path : written) tools::info("wrote " + path);
}

/// "latlong 2048 x 1024"; HEALPix tables also name N_side, since the image size alone reads like a cube cross.
std::string table_grid_description(const envkit::EnvTables& t) {
  std::string text =
      std::string(envkit::kind_name(t.grid())) + " " + std::to_string(t.width()) + " x " + std::to_string(t.height());
  if (t.grid() == envkit::Kind::HEALPix)
    text += " (N_side " + std::to_string(t.width() / 4) + ", 12 base pixels, equal-area texels)";
  return text;
}

/// The sun a bake stored with the tables (envbake --tables ...,sun): looked_for is false when it stored none.
struct StoredSun {
  bool looked_for = false;
  std::optional<envkit::SunEstimate> sun;
};
StoredSun stored_sun(const envkit::EnvTables& t) {
  for (bool compensated : {false, true})
    for (auto m : {envkit::SamplingMethod::Hierarchical, envkit::SamplingMethod::Cdf, envkit::SamplingMethod::Alias})
      if (const auto split = t.stored_sun_split(m, compensated))
        return {true, *split ? std::optional((*split)->sun()) : std::nullopt};
  return {};
}

int describe_tables(const Options& o) {
  const envkit::EnvTables t = envkit::EnvTables::load(o.in.path);
  const StoredSun sun = stored_sun(t);
  if (o.json) {
    json j = json::parse(t.descriptor());
    j["file"] = o.in.path;
    if (sun.looked_for) j["sun"] = sun_json(sun.sun);
    for (const auto& [name, bytes] : t.table_bytes()) j["bytes"][name] = bytes;
    std::cout << tools::json_text(j) << "\n";
  } else {
    const auto row = [](const std::string& key, const std::string& value) {
      std::cout << tools::pad(key, 28) << value << "\n";
    };
    const json d = json::parse(t.descriptor());
    row("file",
        o.in.path + " (envkit sampling tables, format version " + std::to_string(envkit::kTableFormatVersion) + ")");
    row("grid", table_grid_description(t));
    row("importance", std::string(envkit::importance_name(t.importance_mode())) +
                          (t.conservative() ? " (conservative)" : "") + ", total " + tools::fmt(t.total_importance()));
    row("source", t.source_path() + " (content hash " + t.source_hash() + ")");
    if (d.contains("bake") && d["bake"].contains("resampled_from"))
      row("resampled from", d["bake"]["resampled_from"].get<std::string>());
    if (sun.looked_for) row("sun (of the importance)", sun_text(sun.sun));
    const double texels = double(t.width()) * t.height();
    for (const auto& [name, bytes] : t.table_bytes())
      row("  " + name,
          tools::fmt(double(bytes) / (1 << 20), 4) + " MiB, " + tools::fmt(double(bytes) / texels, 3) + " bytes/texel");
    for (const envkit::TableWarning& w : t.warnings()) row("warning", w.message);
  }
  if (!o.export_exr.empty()) export_tables(t, o.in.path, o.export_exr);
  return tools::kExitOk;
}

// Mode: a KTX2 or DDS texture (envprefilter's outputs): what its header says.
int describe_gpu_texture(const Options& o) {
  const envkit::GpuTextureInfo t = envkit::read_gpu_texture_info(o.in.path);
  if (o.json) {
    std::cout << json{{"file", o.in.path},  {"container", t.container},  {"format", t.format},
                      {"width", t.width},   {"height", t.height},        {"faces", t.faces},
                      {"levels", t.levels}, {"key_values", t.key_values}}
                     .dump(2)
              << "\n";
    return tools::kExitOk;
  }
  std::cout << o.in.path << ": " << t.container << " " << t.format << ", " << t.width << "x" << t.height << ", "
            << (t.faces == 6 ? "cube (6 faces)" : "2D") << ", " << t.levels << " levels\n";
  for (const auto& [k, v] : t.key_values) std::cout << "  " << k << ": " << v << "\n";
  return tools::kExitOk;
}

int run(Options& o) {
  if (!envkit::is_face_pattern(o.in.path) && envkit::is_gpu_texture(o.in.path)) return describe_gpu_texture(o);
  if (!envkit::is_face_pattern(o.in.path) && is_table_file(o.in.path)) return describe_tables(o);
  if (!o.export_exr.empty()) throw CLI::ValidationError("--export-exr", "applies to table files (from envbake) only");
  return describe_envmap(o);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app(
      "Describes an environment map (pixels, parameterization, power and statistics per channel) or a "
      "table file from envbake.",
      "envinfo");
  Options o;
  app.add_option("IN", o.in.path, "input map (a '%' reads six cube faces) or table file")
      ->required()
      ->type_name("FILE");
  tools::add_parsed_option(app, "--from", o.in.from, envkit::parse_kind,
                           "parameterization: " + tools::kind_choices() + " (default: detected)")
      ->type_name("KIND");
  tools::add_parsed_option(app, "--layout", o.in.layout, envkit::parse_layout,
                           "cube layout: " + tools::layout_choices() + " (default: detected)")
      ->type_name("L");
  tools::add_parsed_option(
      app, "--convention", o.in.convention, tools::convention_named,
      "convention the map was written for: " + tools::convention_choices() + " (default: from metadata, else envkit)")
      ->type_name("C");
  app.add_flag("--json", o.json, "print one JSON object instead of the table");
  app.add_option("--export-exr", o.export_exr,
                 "table files: write importance, marginal, conditionals and hierarchical "
                 "levels as PREFIX_*.exr")
      ->type_name("PREFIX");
  app.footer(kFooter);
  return tools::run_cli(app, argc, argv, [&] { return run(o); });
}
