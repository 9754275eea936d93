// Loads envkit's OpenImageIO module (image_backend.h) on first need.
#include <envkit/core/error.h>
#include <envkit/core/module_loader.h>

#include "image_backend.h"

namespace envkit::detail {
namespace {

struct Loaded {
  ImageBackend* backend = nullptr;
  std::string error;
};

Loaded load() {
  const ModuleSpec spec{"OpenImageIO", "ENVKIT_OIIO_MODULE", ENVKIT_OIIO_MODULE_INSTALL, ENVKIT_OIIO_MODULE_BUILD,
                        kOiioEntryPoint};
  Loaded r;
  if (void* entry = load_module_entry(spec, r.error)) r.backend = reinterpret_cast<ImageBackend* (*)()>(entry)();
  return r;
}

}  // namespace

ImageBackend& oiio_backend(const std::string& path) {
  static const Loaded loaded = load();  // thread-safe, once
  if (!loaded.backend) fail(path, "this format needs OpenImageIO: " + loaded.error);
  return *loaded.backend;
}

}  // namespace envkit::detail
