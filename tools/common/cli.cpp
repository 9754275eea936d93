#include "common/cli.h"

#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/core/excerpt.h>
#include <envkit/io/image_io.h>
#include <envkit/io/request_limits.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/parameterization.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <limits>
#include <new>
#include <optional>
#include <string_view>

namespace envkit::tools {

namespace {

std::string g_program = "envkit";

// Longest error message printed whole: a value or key a message echoes cannot flood the terminal, and control
// characters in it are escaped, so an error stays one line.
constexpr std::size_t kMessageBytes = 2000;

std::string choices(const std::vector<std::string>& names) { return join(names, "|"); }

}  // namespace

int run_cli(CLI::App& app, int argc, char** argv, const std::function<int()>& body) {
  g_program = app.get_name();
  app.failure_message([](const CLI::App* a, const CLI::Error& e) {
    const std::string full = CLI::FailureMessage::simple(a, e);  // e.what(), then "Run with --help ..."
    return envkit::excerpt(e.what(), kMessageBytes) + full.substr(std::min(full.size(), std::strlen(e.what())));
  });
  try {
    app.parse(argc, argv);
    return body();
  } catch (const CLI::ParseError& e) {
    // CLI11 prints help/version (exit 0) or its message plus "Run with --help"; usage errors all map to 2.
    return app.exit(e) == 0 ? kExitOk : kExitUsage;
  } catch (const std::bad_alloc&) {
    std::cerr << g_program << ": out of memory\n";
  } catch (const std::exception& e) {
    std::cerr << g_program << ": " << envkit::excerpt(envkit::without_temp_names(e.what()), kMessageBytes) << "\n";
  }
  return kExitError;
}

void info(const std::string& message) { std::cerr << g_program << ": " << message << std::endl; }
void warn(const std::string& message) { std::cerr << g_program << ": warning: " << message << std::endl; }

const Convention* convention_named(const std::string& name) { return &convention(name); }

std::string kind_choices() {
  std::vector<std::string> names;
  for (Kind k : kAllKinds) names.push_back(kind_name(k));
  return choices(names);
}

std::string layout_choices() {
  std::vector<std::string> names;
  for (CubeLayout l :
       {CubeLayout::VerticalStrip, CubeLayout::HorizontalStrip, CubeLayout::HorizontalCross, CubeLayout::VerticalCross})
    names.push_back(layout_name(l));
  return choices(names);
}

std::string convention_choices() {
  std::vector<std::string> aliases;
  for (const auto& [alias, preset] : convention_aliases()) aliases.push_back(alias + "=" + preset);
  return choices(convention_names()) + " (aliases: " + join(aliases, ", ") + ")";
}

namespace {

// "%.17g" without trailing noise for range bounds: 1024, 1e+06, 0.5.
std::string bound_text(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

std::string range_text(double lo, double hi, bool min_exclusive) {
  return std::string(min_exclusive ? "(" : "[") + bound_text(lo) + ", " + bound_text(hi) + "]";
}

// Strict double parsing: the whole text, no NaN, no infinities, no overflow (1e999).
std::optional<double> finite_number(const std::string& text) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text.front()))) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || !std::isfinite(v) || errno == ERANGE) return std::nullopt;
  return v;
}

// Checks `text` as an integer in [lo, hi]; returns the message (empty: fine) and the canonical digits in `out`.
std::string check_integer(const std::string& text, long long lo, long long hi, std::string& out) {
  const std::string range = range_text(double(lo), double(hi), false);
  const std::optional<double> v = finite_number(text);
  if (!v) return "'" + text + "' is not a number (expected an integer in " + range + ")";
  if (*v != std::floor(*v)) return "'" + text + "' is not a whole number (expected an integer in " + range + ")";
  if (*v < double(lo) || *v > double(hi)) return text + " is outside " + range;
  // Digits only from here: "1e3" becomes "1000" so CLI11's integer conversion takes it.
  out = std::to_string(static_cast<long long>(*v));
  return {};
}

std::string check_number(const std::string& text, double lo, double hi, bool min_exclusive) {
  const std::string range = range_text(lo, hi, min_exclusive);
  const std::optional<double> v = finite_number(text);
  if (!v) return "'" + text + "' is not a finite number (expected a number in " + range + ")";
  if (*v < lo || *v > hi || (min_exclusive && *v == lo)) return text + " is outside " + range;
  return {};
}

}  // namespace

CLI::Validator integer_in(long long lo, long long hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) {
        std::string canonical = text;
        std::string message = check_integer(text, lo, hi, canonical);
        if (message.empty()) text = canonical;
        return message;
      },
      "INT in " + range_text(double(lo), double(hi), false));
}

CLI::Validator number_in(double lo, double hi, bool min_exclusive) {
  return CLI::Validator(
      [lo, hi, min_exclusive](std::string& text) { return check_number(text, lo, hi, min_exclusive); },
      "NUMBER in " + range_text(lo, hi, min_exclusive));
}

double parse_number(const std::string& option, const std::string& text, double lo, double hi) {
  const std::string message = check_number(text, lo, hi, false);
  if (!message.empty()) throw CLI::ValidationError(option, message);
  return *finite_number(text);
}

long long parse_integer(const std::string& option, const std::string& text, long long lo, long long hi) {
  std::string canonical = text;
  const std::string message = check_integer(text, lo, hi, canonical);
  if (!message.empty()) throw CLI::ValidationError(option, message);
  return std::stoll(canonical);
}

void check_request(const std::string& option, const std::string& value, const std::function<void()>& check) {
  try {
    check();
  } catch (const RequestTooLarge& e) {
    throw CLI::ValidationError(option, "'" + value + "': " + e.what());
  }
}

void check_image_size(const std::string& option, const std::string& value, const std::string& what, long long width,
                      long long height, double bytes_per_texel) {
  check_request(option, value, [&] { check_request_size(what, width, height, bytes_per_texel); });
}

std::string json_text(const nlohmann::json& j, int indent) {
  return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

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

namespace {

// Digits only, as a non-negative integer; values beyond long long read as its maximum (out of every range).
std::optional<long long> whole_number(std::string_view text) {
  if (text.empty() || text.find_first_not_of("0123456789") != std::string_view::npos) return std::nullopt;
  long long value = 0;
  const auto result = std::from_chars(text.data(), text.data() + text.size(), value);
  return result.ec == std::errc::result_out_of_range ? std::numeric_limits<long long>::max() : value;
}

}  // namespace

ImageSize parse_image_size(const std::string& option, const std::string& text, int max_side) {
  const std::size_t x = text.find_first_of("xX");
  std::optional<long long> w, h;
  if (x != std::string::npos) {
    w = whole_number(std::string_view(text).substr(0, x));
    h = whole_number(std::string_view(text).substr(x + 1));
  }
  if (!w || !h) throw CLI::ValidationError(option, "'" + text + "' is not WxH (two whole numbers, e.g. 1024x512)");
  if (*w < 1 || *h < 1 || *w > max_side || *h > max_side)
    throw CLI::ValidationError(option,
                               "'" + text + "': width and height must be in [1, " + std::to_string(max_side) + "]");
  return {int(*w), int(*h)};
}

CLI::Option* add_threads_option(CLI::App& app, int& threads) {
  return app.add_option("--threads", threads, "worker threads (0 = all cores)")
      ->type_name("N")
      ->transform(integer_in(0, 1024));
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
