#pragma once
// JSON parsing that remembers the line of every key, for error messages "file:line: key.path: problem".
#include <map>
#include <nlohmann/json.hpp>
#include <string>

namespace envkit::render {

struct LineTrackedJson {
  nlohmann::json value;
  /// Line (1-based) of each key path ("camera", "camera.fov", "shapes[2]", "shapes[2].material").
  std::map<std::string, int> lines;
  /// Line of `path`, else of its closest recorded ancestor, else 1.
  int line_of(std::string path) const;
};

/// Containers nested deeper than this are refused (no scene needs more than a handful of levels).
inline constexpr std::size_t kMaxJsonDepth = 64;

/// Parses `text`; nesting deeper than kMaxJsonDepth throws Error("<name>:<line>: JSON nested deeper than 64
/// levels"), a number out of double range Error("<name>:<line>: invalid JSON value: ..."); malformed JSON throws
/// Error("<name>:<line>: malformed JSON: <parser message>"), the parser's message cut by excerpt() (it quotes the
/// last token read, which may be megabytes).
LineTrackedJson parse_json_with_lines(const std::string& text, const std::string& name);

}  // namespace envkit::render
