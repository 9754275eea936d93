#pragma once
/// @file cli.h
/// What every envkit command-line tool shares: exit codes, one-line messages prefixed by the program name,
/// options parsed once by libenv's own parsers (so the error text is libenv's), and the thread limit.
#include <envkit/core/error.h>
#include <envkit/core/vec.h>
#include <envkit/maps/convention.h>
#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace envkit::tools {

/// Exit codes shared by the tools (documented in each --help).
inline constexpr int kExitOk = 0;
inline constexpr int kExitError = 1;      ///< bad input, unreadable/unwritable file: one line on stderr
inline constexpr int kExitUsage = 2;      ///< command-line mistake (CLI11's message)
inline constexpr int kExitThreshold = 3;  ///< envdiff: the metric exceeds --fail-above

/// Parses the command line and runs `body`. --help prints and returns 0; CLI11 usage errors (also those thrown
/// by `body` as CLI::ParseError) print CLI11's message and return kExitUsage; envkit::Error and any other
/// exception print ONE line "<program>: <message>" and return kExitError. Messages below use the app's name.
int run_cli(CLI::App& app, int argc, char** argv, const std::function<int()>& body);

/// "<program>: <message>" on stderr: information the user can silence with --quiet (callers decide).
void info(const std::string& message);
/// "<program>: warning: <message>" on stderr.
void warn(const std::string& message);

/// Adds option `name`, one value that libenv's `parse` turns into `target` where CLI11 checks it: each name is
/// parsed once, on its way in, and a value `parse` refuses (envkit::Error) is a usage error "<option>: <libenv's
/// message>". `target` is a T, an std::optional<T>, or a pointer for parsers that return a reference
/// (convention_named); it keeps its value when the option is absent. With several occurrences the last counts.
template <class Target, class Parse>
CLI::Option* add_parsed_option(CLI::App& app, const std::string& name, Target& target, Parse parse,
                               const std::string& help) {
  // The check stores what it parsed, so the option's own callback has nothing left to do.
  CLI::Option* option = app.add_option_function<std::string>(
      name, [](const std::string&) {}, help);
  option->check(CLI::Validator(
      [&target, parse](std::string& text) -> std::string {
        try {
          target = parse(text);
          return {};
        } catch (const envkit::Error& e) {
          return e.what();
        }
      },
      ""));
  return option;
}

/// convention() as a parser for add_parsed_option: the preset, by address (presets live for the program).
const Convention* convention_named(const std::string& name);

/// "a|b|c" lists for help texts.
std::string kind_choices();
std::string layout_choices();
std::string convention_choices();
inline constexpr const char* kFilterChoices = "nearest|bilinear|bicubic|area";

/// Number options, checked where the value enters: every numeric option of every tool uses one of these, so
/// NaN, infinities, fractions where a count is meant and values outside the supported range are refused with
/// one message that names the option, the value and the range ("--threads: -1 is outside [0, 1024]").
/// integer_in accepts decimal integers and integral scientific notation ("1e3" is rewritten to "1000", "1.5" and
/// "1e999" are refused; attach it with ->transform(), which lets it rewrite the value); number_in accepts finite
/// reals (->check()). `min_exclusive`: the lower bound itself is refused.
CLI::Validator integer_in(long long lo, long long hi);
CLI::Validator number_in(double lo, double hi, bool min_exclusive = false);
/// The same check for numbers inside option values (R,G,B lists, pairs): returns the value or throws
/// CLI::ValidationError(option, ...).
double parse_number(const std::string& option, const std::string& text, double lo, double hi);
long long parse_integer(const std::string& option, const std::string& text, long long lo, long long hi);

/// Refuses, up front, an image or table whose size the machine or envkit's readers cannot take: libenv's
/// check_request_size (request_limits.h) for `what` of width x height, bytes_per_texel bytes per texel, its refusal
/// thrown as CLI::ValidationError(option, "'<value>': <what> of W x H ...") naming the option and its value.
void check_image_size(const std::string& option, const std::string& value, const std::string& what, long long width,
                      long long height, double bytes_per_texel);
/// Runs one of libenv's request checks (request_limits.h) for `option`'s value; its RequestTooLarge is thrown as
/// CLI::ValidationError(option, "'<value>': <message>").
void check_request(const std::string& option, const std::string& value, const std::function<void()>& check);

/// JSON text for user-facing output: strings that are not valid UTF-8 (file names are bytes) are written with
/// U+FFFD in place of the invalid bytes instead of failing the dump.
std::string json_text(const nlohmann::json& j, int indent = 2);

/// Parses "X,Y" (two finite numbers); throws CLI::ValidationError naming `option` otherwise.
std::pair<double, double> parse_number_pair(const std::string& option, const std::string& text);

/// An image size in texels.
struct ImageSize {
  int width = 0;
  int height = 0;
};
/// Parses an image size "WxH": two whole decimal numbers joined by 'x' (or 'X'), nothing else (no signs, spaces or
/// exponents), each in [1, max_side]. Every tool's WxH option goes through this one parser, so a malformed or
/// out-of-range size is a usage error (CLI::ValidationError naming `option` and the value: kExitUsage).
ImageSize parse_image_size(const std::string& option, const std::string& text, int max_side);

/// Adds --threads N to `app` (0 = all cores, at most 1024).
CLI::Option* add_threads_option(CLI::App& app, int& threads);
/// Limits oneTBB to `threads` workers while the returned object lives (nothing for 0).
std::unique_ptr<tbb::global_control> limit_threads(int threads);

/// Number formatting for tables: %.*g, and fixed-width columns.
std::string fmt(double value, int precision = 6);
std::string pad(const std::string& text, std::size_t width);   ///< left-aligned
std::string rpad(const std::string& text, std::size_t width);  ///< right-aligned
/// "R, G, B"
std::string join(const std::vector<std::string>& items, const std::string& separator = ", ");
std::string vec_text(const Vec3& v, int precision = 4);

}  // namespace envkit::tools
