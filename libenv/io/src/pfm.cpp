// PFM codec (see image_codecs.h).
#include <envkit/core/error.h>
#include <envkit/io/image_codecs.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <locale>
#include <sstream>

namespace envkit {
namespace {

bool is_space(unsigned char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

}  // namespace

bool looks_like_pfm(std::span<const unsigned char> bytes) {
  return bytes.size() >= 3 && bytes[0] == 'P' && (bytes[1] == 'F' || bytes[1] == 'f') && is_space(bytes[2]);
}

PfmHeader parse_pfm_header(std::span<const unsigned char> bytes, const std::string& name) {
  if (!looks_like_pfm(bytes)) fail(name, "not a PFM file (no \"PF\" or \"Pf\" line)");
  PfmHeader h;
  h.channels = bytes[1] == 'F' ? 3 : 1;
  std::size_t pos = 2;
  // A header token: whitespace, then up to 64 non-space bytes (anything longer is not a PFM number).
  auto token = [&](const char* what) {
    while (pos < bytes.size() && is_space(bytes[pos])) ++pos;
    const std::size_t start = pos;
    while (pos < bytes.size() && !is_space(bytes[pos]) && pos - start < 64) ++pos;
    if (pos == start || pos >= bytes.size() || !is_space(bytes[pos]))
      fail(name, std::string("cannot read: bad or truncated PFM header (") + what + ")");
    return std::string(reinterpret_cast<const char*>(bytes.data()) + start, pos - start);
  };
  auto dimension = [&](const char* what) {
    const std::string t = token(what);
    long long v = -1;
    const auto r = std::from_chars(t.data(), t.data() + t.size(), v);
    // An empty image is no image: every envkit reader refuses 0 x N.
    if (r.ec != std::errc() || r.ptr != t.data() + t.size() || v < 1 || v > std::numeric_limits<int>::max())
      fail(name, std::string("cannot read: bad PFM ") + what + " '" + t + "' (expected a whole number >= 1)");
    return static_cast<int>(v);
  };
  h.width = dimension("width");
  h.height = dimension("height");
  const std::string s = token("scale");
  std::istringstream in(s);
  in.imbue(std::locale::classic());
  double scale = 0;
  std::string rest;
  if (!(in >> scale) || (in >> rest) || !std::isfinite(scale) || scale == 0.0)
    fail(name, "cannot read: bad PFM scale '" + s + "' (a non-zero number; its sign gives the byte order)");
  h.little_endian = scale < 0;
  h.scale = std::abs(scale);
  h.data_offset = pos + 1;  // exactly one whitespace byte ends the header
  return h;
}

Image decode_pfm(FloatBuffer&& data, const PfmHeader& h) {
  Image image;
  image.width = h.width;
  image.height = h.height;
  image.channels = h.channels;
  image.channel_names = h.channels == 3 ? std::vector<std::string>{"R", "G", "B"} : std::vector<std::string>{"Y"};
  image.pixels = std::move(data);
  const std::size_t row = static_cast<std::size_t>(h.width) * static_cast<std::size_t>(h.channels);
  const bool swap = h.little_endian != (std::endian::native == std::endian::little);
  // Rows are stored bottom to top: swap row y with row H-1-y (and fix the byte order on the way).
  const int half = h.height / 2;
  auto fix = [swap](float* p, std::size_t n) {
    if (!swap) return;
    for (std::size_t i = 0; i < n; ++i) {
      std::uint32_t u;
      std::memcpy(&u, p + i, 4);
      u = __builtin_bswap32(u);
      std::memcpy(p + i, &u, 4);
    }
  };
  tbb::parallel_for(tbb::blocked_range<int>(0, half + (h.height % 2), 16), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y != r.end(); ++y) {
      float* a = image.pixels.data() + static_cast<std::size_t>(y) * row;
      float* b = image.pixels.data() + static_cast<std::size_t>(h.height - 1 - y) * row;
      if (a != b) {
        std::swap_ranges(a, a + row, b);
        fix(b, row);
      }
      fix(a, row);
    }
  });
  return image;
}

std::vector<unsigned char> encode_pfm_header(const Image& image) {
  const std::string header = std::string(image.channels == 3 ? "PF" : "Pf") + "\n" + std::to_string(image.width) + " " +
                             std::to_string(image.height) + "\n-1.0\n";
  return {header.begin(), header.end()};
}

}  // namespace envkit
