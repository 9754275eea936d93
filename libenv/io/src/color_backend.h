#pragma once
// What envkit's colour functions (envkit/io/color.h) ask of OpenColorIO, so that the library lives in a module loaded
// on the first question the shipped config's table (color.cpp) cannot answer: libenvkit_ocio.so,
// libenv/io/modules/color_ocio_module.cpp. OpenColorIO's libraries and parsing a config cost every program about 9 ms
// of start-up, while a run that reads and writes float files in the working space never converts a colour.
//
// Each method is the public function of the same name in envkit/io/color.h, with its contract; errors are
// envkit::Error. The module and libenv are built together by the same compiler, so C++ types cross the boundary; the
// entry point's name carries the interface version (kColorEntryPoint), and a module of another version is not found.
#include <envkit/core/image.h>
#include <envkit/core/vec.h>

#include <string>
#include <vector>

namespace envkit::detail {

class ColorBackend {
 public:
  virtual ~ColorBackend() = default;
  virtual std::string working_space() const = 0;
  virtual std::string config_source() const = 0;
  virtual std::vector<std::string> colorspace_names() const = 0;
  virtual std::string canonical_colorspace(const std::string& name) const = 0;
  virtual bool is_data_colorspace(const std::string& name) const = 0;
  virtual void convert_colorspace(Image& image, const std::string& from, const std::string& to) const = 0;
  virtual void decode_gamma(Image& image, double gamma) const = 0;
  virtual Vec3 luminance_weights(const std::string& colorspace) const = 0;
  virtual std::vector<std::string> display_names() const = 0;
  virtual std::vector<std::string> view_names(const std::string& display) const = 0;
  virtual void encode_for_display(Image& image, const std::string& display, const std::string& view) const = 0;
};

/// The module's entry point: extern "C" const ColorBackend* envkit_color_backend_v1(), a process-wide object the
/// module owns.
inline constexpr const char* kColorEntryPoint = "envkit_color_backend_v1";

/// The OpenColorIO module, loaded on first call (dlopen). Throws Error when it is unavailable.
const ColorBackend& color_backend();

}  // namespace envkit::detail
