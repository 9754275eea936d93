#pragma once
/// @file excerpt.h
/// User text echoed in messages, bounded and kept on one line.
#include <cstddef>
#include <cstdio>
#include <string>
#include <string_view>

namespace envkit {

/// Longest user text (a key, a value, a name) that excerpt() echoes whole.
inline constexpr std::size_t kExcerptChars = 60;

/// `text` as it may be echoed in a message: control characters escaped ("\n", "\t", "\x00"), so the message stays
/// one line, and a text longer than `max_bytes` cut to its first `max_bytes` bytes (never inside a UTF-8 sequence)
/// followed by "... (<size> bytes)", so a 2 MB key or value cannot become a 2 MB message.
inline std::string excerpt(std::string_view text, std::size_t max_bytes = kExcerptChars) {
  std::size_t keep = text.size();
  if (keep > max_bytes) {
    keep = max_bytes;
    while (keep > 0 && (static_cast<unsigned char>(text[keep]) & 0xC0) == 0x80) --keep;  // a continuation byte
  }
  std::string out;
  out.reserve(keep + 32);
  for (const char ch : text.substr(0, keep)) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7F) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
    } else {
      out += ch;
    }
  }
  if (keep < text.size()) out += "... (" + std::to_string(text.size()) + " bytes)";
  return out;
}

}  // namespace envkit
