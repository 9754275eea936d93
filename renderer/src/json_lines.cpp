#include "json_lines.h"

#include <envkit/core/error.h>
#include <envkit/core/excerpt.h>

#include <algorithm>
#include <iterator>
#include <vector>

namespace envkit::render {

namespace {

// Longest parser message echoed whole.
constexpr std::size_t kJsonReasonChars = 160;

/// A char iterator that reports how far the parser has read (nlohmann reads through iterator copies).
struct CountingIterator {
  using iterator_category = std::input_iterator_tag;
  using value_type = char;
  using difference_type = std::ptrdiff_t;
  using pointer = const char*;
  using reference = const char&;

  const char* p = nullptr;
  const char* begin = nullptr;
  std::size_t* position = nullptr;

  reference operator*() const { return *p; }
  CountingIterator& operator++() {
    ++p;
    *position = std::size_t(p - begin);
    return *this;
  }
  CountingIterator operator++(int) {
    CountingIterator old = *this;
    ++*this;
    return old;
  }
  bool operator==(const CountingIterator& o) const { return p == o.p; }
  bool operator!=(const CountingIterator& o) const { return p != o.p; }
};

int line_at(const std::string& text, std::size_t byte) {
  byte = std::min(byte, text.size());
  return 1 + int(std::count(text.begin(), text.begin() + std::ptrdiff_t(byte), '\n'));
}

/// line_at for positions that only grow (the parser's): counts the newlines since the previous call, so a
/// document costs O(size) in all instead of O(size) per key.
struct LineCounter {
  const std::string& text;
  std::size_t byte = 0;
  int line = 1;
  int at(std::size_t position) {
    position = std::min(position, text.size());
    if (position < byte) return line_at(text, position);
    line += int(std::count(text.begin() + std::ptrdiff_t(byte), text.begin() + std::ptrdiff_t(position), '\n'));
    byte = position;
    return line;
  }
};

struct Level {
  bool is_array = false;
  std::string path;  // path of this container
  std::string key;   // current key (objects)
  int index = -1;    // current index (arrays)
};

std::string child_path(const Level& level) {
  if (level.is_array) return level.path + "[" + std::to_string(level.index) + "]";
  return level.path.empty() ? level.key : level.path + "." + level.key;
}

}  // namespace

int LineTrackedJson::line_of(std::string path) const {
  while (true) {
    if (auto it = lines.find(path); it != lines.end()) return it->second;
    const std::size_t cut = path.find_last_of(".[");
    if (cut == std::string::npos || path.empty()) return 1;
    path.resize(cut);
  }
}

LineTrackedJson parse_json_with_lines(const std::string& text, const std::string& name) {
  LineTrackedJson result;
  std::size_t position = 0;
  std::vector<Level> stack;
  LineCounter lines{text};
  auto on_value_start = [&]() -> std::string {
    if (stack.empty()) return "";
    Level& top = stack.back();
    if (top.is_array) ++top.index;
    return child_path(top);
  };
  nlohmann::json::parser_callback_t callback = [&](int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using E = nlohmann::json::parse_event_t;
    switch (event) {
      case E::object_start:
      case E::array_start: {
        // Bounded nesting: deep brackets cost the parser and the key paths memory and time per level, and no
        // scene needs more than a few levels.
        if (stack.size() >= kMaxJsonDepth)
          throw Error(name + ":" + std::to_string(lines.at(position)) + ": JSON nested deeper than " +
                      std::to_string(kMaxJsonDepth) + " levels");
        const std::string path = on_value_start();
        if (!path.empty() && stack.back().is_array) result.lines.emplace(path, lines.at(position));
        stack.push_back(Level{event == E::array_start, path, "", -1});
        break;
      }
      case E::object_end:
      case E::array_end:
        if (!stack.empty()) stack.pop_back();
        break;
      case E::key:
        if (!stack.empty()) {
          stack.back().key = parsed.get<std::string>();
          result.lines[child_path(stack.back())] = lines.at(position);
        }
        break;
      case E::value:
        if (!stack.empty() && stack.back().is_array) {
          const std::string path = on_value_start();
          result.lines.emplace(path, lines.at(position));
        }
        break;
    }
    return true;
  };
  CountingIterator first{text.data(), text.data(), &position};
  CountingIterator last{text.data() + text.size(), text.data(), &position};
  try {
    result.value = nlohmann::json::parse(first, last, callback, true, true);  // comments allowed
  } catch (const nlohmann::json::parse_error& e) {
    std::string message = e.what();
    // "[json.exception.parse_error.101] parse error at line 3, column 5: syntax error ..." -> keep the reason.
    // The reason quotes what was last read (a whole string token, however long): cut, on one line.
    if (const std::size_t colon = message.find(": "); colon != std::string::npos) message = message.substr(colon + 2);
    throw Error(name + ":" + std::to_string(line_at(text, e.byte == 0 ? 0 : e.byte - 1)) +
                ": malformed JSON: " + excerpt(message, kJsonReasonChars));
  } catch (const nlohmann::json::exception& e) {
    // Not a syntax error but a value the parser cannot hold (a number like 1e999 overflows a double).
    std::string message = e.what();
    if (const std::size_t bracket = message.find("] "); bracket != std::string::npos)
      message = message.substr(bracket + 2);
    throw Error(name + ":" + std::to_string(line_at(text, position)) +
                ": invalid JSON value: " + excerpt(message, kJsonReasonChars));
  }
  return result;
}

}  // namespace envkit::render
