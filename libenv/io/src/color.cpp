// envkit's colour functions (envkit/io/color.h). OpenColorIO lives in a module (color_backend.h); what every float file
// read and write asks (the working space, whether a file's space is it, the working space's luminance) is answered
// here from a table of the shipped config while that config is the active one, without loading the module.
#include <envkit/core/error.h>
#include <envkit/core/module_loader.h>
#include <envkit/io/color.h>

#include <cstdlib>
#include <cstring>
#include <string>

#include "color_backend.h"

namespace envkit {
namespace detail {
namespace {

struct Loaded {
  const ColorBackend* backend = nullptr;
  std::string error;
};

Loaded load() {
  const ModuleSpec spec{"OpenColorIO", "ENVKIT_OCIO_MODULE", ENVKIT_OCIO_MODULE_INSTALL, ENVKIT_OCIO_MODULE_BUILD,
                        kColorEntryPoint};
  Loaded r;
  if (void* entry = load_module_entry(spec, r.error)) r.backend = reinterpret_cast<const ColorBackend* (*)()>(entry)();
  return r;
}

}  // namespace

const ColorBackend& color_backend() {
  static const Loaded loaded = load();  // thread-safe, once
  if (!loaded.backend) throw Error("colour management needs " + loaded.error);
  return *loaded.backend;
}

}  // namespace detail

namespace {

/// A name of libenv/data/ocio/config.ocio as OCIO resolves it. Exact spellings only: anything else (other cases,
/// aliases, the other spaces) goes to OCIO. The test ColorTest.ShippedTableAnswersAsOpenColorIODoes holds each row
/// to OCIO's answer from that file.
struct ShippedName {
  const char* name;
  const char* canonical;
  bool data;
};
constexpr ShippedName kShippedNames[] = {{"lin_rec709", "lin_rec709", false},
                                         {"scene_linear", "lin_rec709", false},
                                         {"srgb", "srgb", false},
                                         {"rec709", "rec709", false},
                                         {"raw", "raw", true},
                                         {"data", "raw", true}};
constexpr const char* kShippedWorkingSpace = "lin_rec709";
/// The shipped config's `luma`: the working space's luminance weights.
constexpr Vec3 kShippedLuma{0.2126, 0.7152, 0.0722};

bool shipped_config_active() {
  const char* ocio = std::getenv("OCIO");
  const char* own = std::getenv("ENVKIT_OCIO_CONFIG");
  return (!ocio || !*ocio) && (!own || !*own);
}

/// The row for `name`, or nullptr when another config is active or the table does not hold the name.
const ShippedName* shipped(const std::string& name) {
  if (!shipped_config_active()) return nullptr;
  for (const ShippedName& row : kShippedNames)
    if (name == row.name) return &row;
  return nullptr;
}

}  // namespace

std::string working_space() {
  return shipped_config_active() ? kShippedWorkingSpace : detail::color_backend().working_space();
}

std::string color_config_source() { return detail::color_backend().config_source(); }

std::vector<std::string> colorspace_names() { return detail::color_backend().colorspace_names(); }

std::string canonical_colorspace(const std::string& name) {
  if (const ShippedName* row = shipped(name)) return row->canonical;
  return detail::color_backend().canonical_colorspace(name);
}

bool is_data_colorspace(const std::string& name) {
  if (const ShippedName* row = shipped(name)) return row->data;
  return detail::color_backend().is_data_colorspace(name);
}

void convert_colorspace(Image& image, const std::string& from, const std::string& to) {
  const ShippedName* src = shipped(from);
  const ShippedName* dst = shipped(to);
  if (src && dst && std::strcmp(src->canonical, dst->canonical) == 0) return;  // the same space: nothing to do
  detail::color_backend().convert_colorspace(image, from, to);
}

void decode_gamma(Image& image, double gamma) { detail::color_backend().decode_gamma(image, gamma); }

Vec3 luminance_weights(const std::string& colorspace) {
  if (const ShippedName* row = shipped(colorspace); row && std::strcmp(row->canonical, kShippedWorkingSpace) == 0)
    return kShippedLuma;
  return detail::color_backend().luminance_weights(colorspace);
}

std::vector<std::string> display_names() { return detail::color_backend().display_names(); }

std::vector<std::string> view_names(const std::string& display) { return detail::color_backend().view_names(display); }

void encode_for_display(Image& image, const std::string& display, const std::string& view) {
  detail::color_backend().encode_for_display(image, display, view);
}

}  // namespace envkit
