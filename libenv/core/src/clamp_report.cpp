#include <envkit/core/clamp_report.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>

namespace envkit {

namespace {

std::string number(double v, int digits = 4) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

}  // namespace

void ClampReport::add(const ClampReport& other) {
  if (format.empty()) {
    format = other.format;
    format_max = other.format_max;
  }
  above += other.above;
  largest = std::max(largest, other.largest);
  negative += other.negative;
  lowest = std::min(lowest, other.lowest);
}

std::string ClampReport::message(const std::string& path) const {
  if (!any()) return "";
  std::string m = path + ": ";
  if (above > 0) {
    m += std::to_string(above) + (above == 1 ? " value" : " values") + " above " + format + "'s largest " +
         number(format_max, 6) + (format == "rg11b10f" ? " (64512 in blue)" : "") + (above == 1 ? " was" : " were") +
         " clamped (largest " + number(largest) + ")";
  }
  if (negative > 0) {
    m += std::string(above > 0 ? " and " : "") + std::to_string(negative) +
         (negative == 1 ? " negative value" : " negative values") + " of the unsigned " + format +
         (negative == 1 ? " was" : " were") + " stored as 0 (lowest " + number(lowest) + ")";
  }
  return m + (above > 0 ? "; use a float output to keep the sun" : "; use a float output to keep them");
}

namespace {

/// The largest float not above `max` (a float that passes `v <= it` passes `v <= max`).
float float_at_most(double max) {
  float f = static_cast<float>(max);
  if (static_cast<double>(f) > max) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

/// Whether every value of the block [v, v + n) is finite and one the format holds, when every channel is examined
/// against one largest value: one loop without branches (the compiler vectorises it). False sends the block to the
/// value-by-value count, which alone decides what is counted.
bool block_fits(const float* v, std::size_t n, float max, bool is_signed) {
  std::uint32_t outside = 0;
  if (is_signed)
    for (std::size_t i = 0; i < n; ++i) outside += std::abs(v[i]) <= max ? 0u : 1u;  // NaN and Inf fail
  else
    for (std::size_t i = 0; i < n; ++i) outside += (v[i] >= 0.0f) & (v[i] <= max) ? 0u : 1u;
  return outside == 0;
}

}  // namespace

ClampReport count_clamped(std::span<const float> pixels, int channels, int used, const FormatRange& range) {
  ClampReport none;
  none.format = range.name;
  none.format_max = range.max[0];
  const std::size_t texels = channels > 0 ? pixels.size() / std::size_t(channels) : 0;
  // Every channel against one largest value: blocks that hold nothing to count are passed over in one loop each.
  const bool flat = used == channels && range.max[0] == range.max[1] && range.max[1] == range.max[2];
  const float flat_max = float_at_most(range.max[0]);
  constexpr std::size_t kBlockTexels = 1024;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, texels, 16384), none,
      [&](const tbb::blocked_range<std::size_t>& r, ClampReport report) {
        for (std::size_t t0 = r.begin(); t0 < r.end(); t0 += kBlockTexels) {
          const std::size_t t1 = std::min(r.end(), t0 + kBlockTexels);
          if (flat && block_fits(pixels.data() + t0 * std::size_t(channels), (t1 - t0) * std::size_t(channels),
                                 flat_max, range.is_signed))
            continue;
          for (std::size_t t = t0; t != t1; ++t)
            for (int c = 0; c < used; ++c) {
              const double v = pixels[t * std::size_t(channels) + std::size_t(c)];
              if (!std::isfinite(v)) continue;
              const double magnitude = range.is_signed ? std::abs(v) : v;
              if (magnitude > range.max[std::min(c, 2)]) {
                ++report.above;
                report.largest = std::max(report.largest, magnitude);
              } else if (!range.is_signed && v < 0.0) {
                ++report.negative;
                report.lowest = std::min(report.lowest, v);
              }
            }
        }
        return report;
      },
      [](ClampReport a, const ClampReport& b) {
        a.add(b);
        return a;
      });
}

}  // namespace envkit
