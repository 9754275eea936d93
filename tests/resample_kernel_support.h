#pragma once
// Shared by the resample kernel tests (test_resample_gather, test_resample_scatter): named maps, a map with detail at
// every scale and the relative difference the kernels are held to.
#include <envkit/core/image.h>
#include <envkit/maps/parameterization.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

namespace envkit::testing {

struct Named {
  std::string name;
  std::shared_ptr<Parameterization> p;
};

// Detail at every scale, strictly positive, from the texel centres' directions; channel 3 an alpha in [0.25, 1] when
// there are 4 channels.
inline Image detailed(const Parameterization& p, int channels) {
  Image img(p.width(), p.height(), channels);
  for (int j = 0; j < p.height(); ++j)
    for (int i = 0; i < p.width(); ++i) {
      Vec3 d;
      if (!p.to_direction(Vec2(i + 0.5, j + 0.5), d)) continue;
      const double ripple = 1.0 + 0.5 * std::sin(23.0 * d.x) * std::cos(17.0 * d.y + 5.0 * d.z);
      for (int c = 0; c < channels; ++c)
        img.at(i, j, c) = static_cast<float>((0.4 + 0.3 * c + 0.2 * d.y) * ripple + 0.1);
      if (channels == 4) img.at(i, j, 3) = static_cast<float>(0.625 + 0.375 * std::sin(9.0 * d.z));
    }
  return img;
}

// Largest |a - b| / max(|a|, |b|) over every channel of every texel (0 where both are 0).
inline double max_relative_difference(const Image& a, const Image& b) {
  double worst = 0.0;
  for (std::size_t k = 0; k < a.pixels.size(); ++k) {
    const double x = a.pixels[k], y = b.pixels[k], scale = std::max(std::abs(x), std::abs(y));
    if (scale > 0.0) worst = std::max(worst, std::abs(x - y) / scale);
  }
  return worst;
}

}  // namespace envkit::testing
