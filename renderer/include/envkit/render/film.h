#pragma once
/// @file film.h
/// Per-pixel accumulation of radiance samples (double), and the outputs: the mean (linear Rec.709 radiance),
/// the variance OF THE MEAN per channel (sample variance / n, unbiased, 0 when n < 2) and the sample count; and,
/// when the render measured it (RenderOptions::pixel_seconds), the seconds spent on each pixel's samples.
#include <envkit/core/image.h>
#include <envkit/core/vec.h>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace envkit::render {

/// A window [x0, x1) x [y0, y1) of the full image, in pixels.
struct Crop {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
};

class Film {
 public:
  /// What a pixel's outputs are computed from: the sum and the sum of squares of its samples, and their count.
  /// A pixel's samples do not depend on the window rendered (render.h), so films of windows rendered apart (a
  /// farm's tiles) merge exactly by copying these into a film of the whole.
  struct Pixel {
    Vec3 sum{0, 0, 0};
    Vec3 sum_sq{0, 0, 0};
    std::uint64_t count = 0;
  };

  Film() = default;
  /// A film covering `crop` of a full_width x full_height image.
  Film(int full_width, int full_height, Crop crop);

  /// Adds one sample to pixel (x, y) of the FILM (crop-relative). Not thread-safe for the same pixel.
  void add(int x, int y, const Vec3& value) {
    Pixel& p = pixel(x, y);
    p.sum += value;
    p.sum_sq += Vec3(value.x * value.x, value.y * value.y, value.z * value.z);
    ++p.count;
  }

  Vec3 mean(int x, int y) const;
  /// Variance of the pixel mean per channel (sample variance / n).
  Vec3 variance(int x, int y) const;
  std::uint64_t count(int x, int y) const { return pixel(x, y).count; }
  /// The sums of pixel (x, y) of the FILM (crop-relative).
  const Pixel& pixel(int x, int y) const { return pixels_[std::size_t(y) * crop_.width() + x]; }
  Pixel& pixel(int x, int y) { return pixels_[std::size_t(y) * crop_.width() + x]; }

  int width() const { return crop_.width(); }
  int height() const { return crop_.height(); }
  const Crop& crop() const { return crop_; }
  int full_width() const { return full_width_; }
  int full_height() const { return full_height_; }
  std::uint64_t total_samples() const;

  /// Seconds spent on pixels' samples, kept only when timed() (the film was made to hold them): a region's cost is
  /// the sum over its pixels. Not thread-safe for the same pixel, like add().
  bool timed() const { return !seconds_.empty(); }
  void set_timed() { seconds_.assign(pixels_.size(), 0.0); }
  void add_seconds(int x, int y, double s) { seconds_[std::size_t(y) * crop_.width() + x] += s; }
  double seconds(int x, int y) const { return timed() ? seconds_[std::size_t(y) * crop_.width() + x] : 0.0; }

  /// Mean as an RGB image (working space).
  Image mean_image() const;
  /// Writes a two-part EXR (float): part 0 "beauty" with R, G, B (the mean; what single-part readers such as
  /// envinfo/envdiff see), part 1 "aov" with variance.R, variance.G, variance.B (variance of the mean) and
  /// samples, and seconds (per pixel, timed() films only: the channel's values differ from run to run). With a
  /// crop, the data window is the crop inside the full display window. Atomic (temp + rename).
  void write_exr(const std::string& path, const std::map<std::string, std::string>& metadata = {}) const;
  /// Writes a display-referred preview (.png) through the OCIO display transform (color.h encode_for_display).
  void write_preview(const std::string& path, const std::string& view = "ACES 1.0 - SDR Video") const;

 private:
  int full_width_ = 0, full_height_ = 0;
  Crop crop_;
  std::vector<Pixel> pixels_;
  std::vector<double> seconds_;  // per pixel when timed(), else empty
};

}  // namespace envkit::render
