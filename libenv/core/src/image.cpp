#include <envkit/core/image.h>

namespace envkit {

Image::Image(int w, int h, int c)
    : width(w),
      height(h),
      channels(c),
      channel_names(default_channel_names(c)),
      alpha_channel(c == 2 || c == 4 ? c - 1 : -1),
      pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * static_cast<std::size_t>(c), 0.0f) {}

std::vector<std::string> default_channel_names(int channels) {
  switch (channels) {
    case 1:
      return {"Y"};
    case 2:
      return {"Y", "A"};
    case 3:
      return {"R", "G", "B"};
    case 4:
      return {"R", "G", "B", "A"};
    default: {
      std::vector<std::string> names;
      for (int c = 0; c < channels; ++c) names.push_back("C" + std::to_string(c));
      return names;
    }
  }
}

}  // namespace envkit
