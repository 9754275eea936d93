#pragma once
/// @file clamp_report.h
/// What an output's texel format could not hold. Writers of range-limited formats (OpenEXR half, KTX2/DDS rgba16f,
/// rg11b10f and rgb9e5, Radiance RGBE: image_io.h, ktx2.h, dds.h, exr_cube_mips.h, ibl_files.h) store values beyond
/// the format's largest finite value as that value and, for the unsigned formats, negative values as 0; they return
/// this report instead of printing, and the caller (a tool, the Python module) turns message() into its warning.
///
/// Largest finite values (radiance units of the image): half 65504; rg11b10f 65024 in red and green, 64512 in blue;
/// rgb9e5 65408. A real sun (1e5 to 1e9) does not fit any of them: only float outputs keep it.
#include <cstddef>
#include <span>
#include <string>

namespace envkit {

struct ClampReport {
  std::string format;        ///< the format: half, rgba16f, rg11b10f, rgb9e5 or rgbe (Radiance); empty when none
  double format_max = 0.0;   ///< its largest finite value (rg11b10f: red and green)
  std::size_t above = 0;     ///< values above the largest (half: in magnitude), stored as +/- the largest
  double largest = 0.0;      ///< the largest magnitude among them; 0 when above == 0
  std::size_t negative = 0;  ///< negative values an unsigned format stored as 0
  double lowest = 0.0;       ///< the most negative among them; 0 when negative == 0

  bool any() const { return above + negative > 0; }
  /// Adds the counts of `other` (another level or face of the same output); takes its format when this has none.
  void add(const ClampReport& other);
  /// One line for the user, e.g. "out.exr: 1234 values above half's largest 65504 were clamped (largest
  /// 1.2e+06); use a float output to keep the sun". Empty when !any().
  std::string message(const std::string& path) const;
};

/// Range of a texel format, per colour channel.
struct FormatRange {
  const char* name;
  double max[3];   ///< largest finite value of channels 0, 1, 2 (channels past 2 use max[2])
  bool is_signed;  ///< false: negative values are stored as 0
};
inline constexpr FormatRange kHalfRange{"half", {65504.0, 65504.0, 65504.0}, true};

/// Counts the values of `pixels` (interleaved, `channels` per texel; channels [0, used) examined) that `range`
/// cannot hold, on all cores. NaN and Inf are not counted (image writers refuse them; packed formats store 0).
ClampReport count_clamped(std::span<const float> pixels, int channels, int used, const FormatRange& range);

}  // namespace envkit
