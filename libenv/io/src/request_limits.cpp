#include <envkit/core/input_checks.h>
#include <envkit/io/image_io.h>
#include <envkit/io/request_limits.h>

#include <cstdio>
#include <limits>

namespace envkit {

namespace {

std::string gib(double bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g GiB", bytes / double(1 << 30));
  return buf;
}

}  // namespace

long long max_request_texels() { return ReadOptions{}.max_texels; }

void check_request_size(const std::string& what, long long width, long long height, double bytes_per_texel) {
  // In double: a product of two requested sides can overflow 64 bits.
  const double texels = double(width) * double(height), bytes = texels * bytes_per_texel;
  const std::string size = what + " of " + std::to_string(width) + " x " + std::to_string(height);
  if (texels > double(max_request_texels())) {
    char count[32];
    std::snprintf(count, sizeof count, "%.4g", texels);
    throw RequestTooLarge(size + " = " + count + " texels is more than envkit's image readers accept (" +
                              std::to_string(max_request_texels()) + ")",
                          what, width, height, bytes);
  }
  const std::uint64_t available = available_memory_bytes();
  if (available != std::numeric_limits<std::uint64_t>::max() && bytes > double(available))
    throw RequestTooLarge(size + " needs about " + gib(bytes) + " of memory; " + gib(double(available)) + " available",
                          what, width, height, bytes);
}

namespace {

void check_at_most(const std::string& what, int size, int max, const std::string& why, double bytes) {
  if (size > max)
    throw RequestTooLarge(
        what + " of side " + std::to_string(size) + " is more than " + std::to_string(max) + ": " + why, what, size,
        size, bytes);
}

std::string map_kind(bool octahedral) { return octahedral ? "octahedral" : "cube"; }
long long map_rows(bool octahedral, int size) { return octahedral ? size : 6LL * size; }

}  // namespace

void check_prefilter_size(int size, bool octahedral) {
  const std::string what = "a GGX chain (" + map_kind(octahedral) + ")";
  check_at_most(what, size, kMaxPrefilterSize, "the largest level 0 envkit prefilters",
                double(size) * double(map_rows(octahedral, size)) * kPrefilterBytesPerTexel);
  check_request_size(what, size, map_rows(octahedral, size), kPrefilterBytesPerTexel);
}

void check_irradiance_size(int size, bool octahedral) {
  const std::string what = "an irradiance map (" + map_kind(octahedral) + ")";
  check_at_most(what, size, kMaxIrradianceSize,
                "irradiance varies slowly, so larger maps add no visible detail and take minutes to compute",
                double(size) * double(map_rows(octahedral, size)) * kIrradianceBytesPerTexel);
  check_request_size(what, size, map_rows(octahedral, size), kIrradianceBytesPerTexel);
}

void check_dfg_lut_size(int size) {
  check_at_most("a DFG table", size, kMaxDfgLutSize,
                "the table varies smoothly, so larger ones add no visible detail and take minutes to compute",
                double(size) * double(size) * 4.0 * sizeof(float));
}

}  // namespace envkit
