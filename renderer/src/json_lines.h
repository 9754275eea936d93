#pragma once
// JSON parsing that remembers the line of every key, for error messages "file:line: key.path: problem".
#include <nlohmann/json.hpp>

#include <map>
#include <string>

namespace envkit::render {

struct LineTrackedJson {
  nlohmann::json value;
  /// Line (1-based) of each key path ("camera", "camera.fov", "shapes[2]", "shapes[2].material").
  std::map<std::string, int> lines;
  /// Line of `path`, else of its closest recorded ancestor, else 1.
  int line_of(std::string path) const;
};

/// Parses `text`; malformed JSON throws Error("<name>:<line>: malformed JSON: <parser message>").
LineTrackedJson parse_json_with_lines(const std::string& text, const std::string& name);

}  // namespace envkit::render
