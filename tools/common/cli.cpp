#include "common/cli.h"

#include <envkit/color.h>
#include <envkit/convention.h>
#include <envkit/cubemap.h>
#include <envkit/error.h>
#include <envkit/filter.h>
#include <envkit/parameterization.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <new>

namespace envkit::tools {

namespace {

std::string g_program = "envkit";

// A validator that runs a libenv parser and reports its Error message (already one line, names the value).
template <class Parse>
CLI::Validator parsed_by(Parse parse) {
  return CLI::Validator(
      [parse](std::string& text) -> std::string {
        try {
          parse(text);
          return {};
        } catch (const envkit::Error& e) {
          return e.what();
        }
      },
      "");
}

std::string choices(const std::vector<std::string>& names) { return join(names, "|"); }

}  // namespace

int run_cli(CLI::App& app, int argc, char** argv, const std::function<int()>& body) {
  g_program = app.get_name();
  try {
    app.parse(argc, argv);
    return body();
  } catch (const CLI::ParseError& e) {
    // CLI11 prints help/version (exit 0) or its message plus "Run with --help"; usage errors all map to 2.
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  } catch (const std::bad_alloc&) {
    std::cerr << g_program << ": out of memory\n";
  } catch (const std::exception& e) {
    std::cerr << g_program << ": " << e.what() << "\n";
  }
  return kExitError;
}

void info(const std::string& message) { std::cerr << g_program << ": " << message << std::endl; }
void warn(const std::string& message) { std::cerr << g_program << ": warning: " << message << std::endl; }

CLI::Validator kind_validator() {
  return parsed_by([](const std::string& s) { parse_kind(s); });
}
CLI::Validator layout_validator() {
  return parsed_by([](const std::string& s) { parse_layout(s); });
}
CLI::Validator convention_validator() {
  return parsed_by([](const std::string& s) { convention(s); });
}
CLI::Validator filter_validator() {
  return parsed_by([](const std::string& s) { parse_filter(s); });
}
CLI::Validator rotation_validator() {
  return parsed_by([](const std::string& s) { parse_rotation(s); });
}
CLI::Validator colorspace_validator() {
  return parsed_by([](const std::string& s) { canonical_colorspace(s); });
}

std::string kind_choices() {
  std::vector<std::string> names;
  for (Kind k : {Kind::LatLong, Kind::CubeMap, Kind::MirrorBall, Kind::AngularMap, Kind::Octahedral,
                 Kind::DualParaboloid})
    names.push_back(kind_name(k));
  return choices(names);
}

std::string layout_choices() {
  std::vector<std::string> names;
  for (CubeLayout l : {CubeLayout::VerticalStrip, CubeLayout::HorizontalStrip, CubeLayout::HorizontalCross,
                       CubeLayout::VerticalCross})
    names.push_back(layout_name(l));
  return choices(names);
}

std::string convention_choices() { return choices(convention_names()); }

std::pair<double, double> parse_number_pair(const std::string& option, const std::string& text) {
  const auto comma = text.find(',');
  try {
    if (comma == std::string::npos) throw std::invalid_argument(text);
    const std::string a = text.substr(0, comma), b = text.substr(comma + 1);
    std::size_t used_a = 0, used_b = 0;
    const double x = std::stod(a, &used_a), y = std::stod(b, &used_b);
    if (used_a != a.size() || used_b != b.size() || !std::isfinite(x) || !std::isfinite(y))
      throw std::invalid_argument(text);
    return {x, y};
  } catch (const std::exception&) {
    throw CLI::ValidationError(option, "'" + text + "' is not two numbers X,Y");
  }
}

CLI::Option* add_threads_option(CLI::App& app, int& threads) {
  return app.add_option("--threads", threads, "worker threads (0 = all cores)")
      ->type_name("N")
      ->check(CLI::NonNegativeNumber);
}

std::unique_ptr<tbb::global_control> limit_threads(int threads) {
  if (threads <= 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               static_cast<std::size_t>(threads));
}

std::string fmt(double value, int precision) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", precision, value);
  return buf;
}

std::string pad(const std::string& text, std::size_t width) {
  return text.size() >= width ? text : text + std::string(width - text.size(), ' ');
}

std::string rpad(const std::string& text, std::size_t width) {
  return text.size() >= width ? text : std::string(width - text.size(), ' ') + text;
}

std::string join(const std::vector<std::string>& items, const std::string& separator) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) out += (i ? separator : "") + items[i];
  return out;
}

std::string vec_text(const Vec3& v, int precision) {
  return "(" + fmt(v.x, precision) + ", " + fmt(v.y, precision) + ", " + fmt(v.z, precision) + ")";
}

}  // namespace envkit::tools
