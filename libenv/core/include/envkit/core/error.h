#pragma once
/// @file error.h
/// The one exception type libenv throws. Its message is a single line meant for users:
/// "<file>: <problem>" when a file is involved, so tools can print it verbatim and exit non-zero.
#include <cstdio>
#include <stdexcept>
#include <string>

namespace envkit {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

/// A number as messages print it: %g (six significant digits; 1e-06, 65504, 1.5e+09).
inline std::string number_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

/// Throws Error("<path>: <problem>").
[[noreturn]] inline void fail(const std::string& path, const std::string& problem) {
  throw Error(path.empty() ? problem : path + ": " + problem);
}

}  // namespace envkit
