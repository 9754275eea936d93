#pragma once
/// @file image.h
/// A float image in linear light, interleaved channels, row-major with row 0 at the top.
/// Colour is associated with alpha (premultiplied), as in OpenEXR and OIIO.
/// Texel (x, y) occupies [x, x+1) x [y, y+1) in continuous image coordinates; its centre is (x+0.5, y+0.5).
#include <envkit/core/pixel_buffer.h>

#include <cstddef>
#include <map>
#include <string>
#include <vector>

namespace envkit {

struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  /// Channel names ("R","G","B","A",...); size == channels.
  std::vector<std::string> channel_names;
  /// Index of the alpha/coverage channel, or -1.
  int alpha_channel = -1;
  /// width * height * channels floats: the image's own (huge-page backed when large: see huge_page_allocator.h) or
  /// borrowed from a caller (pixel_buffer.h).
  PixelBuffer pixels;
  /// Free-form string metadata carried from input to output (envkit:* keys are envkit's own).
  std::map<std::string, std::string> metadata;

  Image() = default;
  Image(int w, int h, int c);

  float* at(int x, int y) { return pixels.data() + (static_cast<std::size_t>(y) * width + x) * channels; }
  const float* at(int x, int y) const { return pixels.data() + (static_cast<std::size_t>(y) * width + x) * channels; }
  float& at(int x, int y, int c) { return at(x, y)[c]; }
  float at(int x, int y, int c) const { return at(x, y)[c]; }
  std::size_t texel_count() const { return static_cast<std::size_t>(width) * height; }
  bool empty() const { return width <= 0 || height <= 0 || channels <= 0; }
  /// Number of colour (non-alpha) channels.
  int color_channels() const { return alpha_channel >= 0 ? channels - 1 : channels; }
};

/// Default channel names for a channel count: Y, YA, RGB, RGBA, then C0.. for more.
std::vector<std::string> default_channel_names(int channels);

}  // namespace envkit
