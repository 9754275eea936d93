#pragma once
/// @file request_limits.h
/// The one up-front check of a requested output size, shared by every entry point that makes an image whose size
/// the user chose (the CLI tools' --size/--resolution options, the renderer's camera resolution, the Python
/// functions' size arguments). It runs before anything is allocated or computed, so an oversized request is refused
/// at once with the quantity, its size and the memory it needs, instead of failing late with "out of memory"
/// (std::bad_alloc) or running for minutes.
///
/// Callers name the request in their own terms: the CLI maps RequestTooLarge to a usage error naming the option, the
/// Python module to a ValueError naming the argument.
#include <envkit/core/error.h>

#include <cstdint>
#include <string>

namespace envkit {

/// An output too large to make: `what` (e.g. "latlong output"), its size in texels, the memory it needs and why
/// it was refused. what() is the one-line message "<what> of W x H ...".
class RequestTooLarge : public Error {
 public:
  RequestTooLarge(const std::string& message, std::string what, long long width, long long height, double bytes)
      : Error(message), what_(std::move(what)), width_(width), height_(height), bytes_(bytes) {}
  const std::string& requested() const { return what_; }
  long long width() const { return width_; }
  long long height() const { return height_; }
  /// Bytes the request needs (every buffer held per output texel), an estimate.
  double bytes_needed() const { return bytes_; }

 private:
  std::string what_;
  long long width_, height_;
  double bytes_;
};

/// The largest texel count of one output image: what envkit's image readers accept (ReadOptions::max_texels), so
/// every image envkit writes can be read back.
long long max_request_texels();

/// Throws RequestTooLarge unless an output of `width` x `height` texels, holding `bytes_per_texel` bytes per texel
/// in all (output, intermediate buffers), can be made: width * height <= max_request_texels() and the bytes fit in
/// available_memory_bytes() (input_checks.h). Messages: "<what> of W x H = N texels is more than envkit's image
/// readers accept (M)" and "<what> of W x H needs about X GiB of memory; Y GiB available".
void check_request_size(const std::string& what, long long width, long long height, double bytes_per_texel);

/// Sizes beyond which the IBL computations take minutes for no gain: irradiance and the DFG lookup table vary
/// smoothly, so larger tables add no detail a renderer can see.
inline constexpr int kMaxIrradianceSize = 512;
inline constexpr int kMaxDfgLutSize = 1024;
/// The largest GGX chain level 0 face.
inline constexpr int kMaxPrefilterSize = 4096;

/// Memory estimates per output texel (bytes) for check_request_size, from the peak resident size of runs: a GGX
/// chain (float RGBA levels, the gathered source cube and the per-level work buffers) and an irradiance map (float
/// RGBA, the quadrature's per-texel direction and weight tables), per face texel (times 6 faces for a cube);
/// sampling tables (envbake --size / --resolution: the importance map and every table over its grid).
inline constexpr double kPrefilterBytesPerTexel = 32.0;
inline constexpr double kIrradianceBytesPerTexel = 224.0;
inline constexpr double kBakeBytesPerTexel = 40.0;

/// The checks of the IBL outputs (envprefilter --size, --irradiance-size, --lut-size and the Python functions
/// prefilter, irradiance, dfg_lut): the bounds above (RequestTooLarge saying the bound and why), then
/// check_request_size for the map (six faces of size x size for a cube, one square for an octahedral map).
void check_prefilter_size(int size, bool octahedral);
void check_irradiance_size(int size, bool octahedral);
void check_dfg_lut_size(int size);

}  // namespace envkit
