// Loads envkit's OpenImageIO module (image_backend.h) on first need.
#include <dlfcn.h>
#include <envkit/error.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>

#include "image_backend.h"

namespace envkit::detail {
namespace {

/// Where the module is looked for: $ENVKIT_OIIO_MODULE, then the installed copy, then the build tree's.
std::vector<std::string> candidates() {
  std::vector<std::string> out;
  if (const char* env = std::getenv("ENVKIT_OIIO_MODULE"); env && *env) out.emplace_back(env);
  out.emplace_back(ENVKIT_OIIO_MODULE_INSTALL);
  out.emplace_back(ENVKIT_OIIO_MODULE_BUILD);
  return out;
}

struct Loaded {
  ImageBackend* backend = nullptr;
  std::string error;
};

Loaded load() {
  Loaded r;
  std::string tried;
  for (const std::string& file : candidates()) {
    std::error_code ec;
    if (!std::filesystem::exists(file, ec)) {
      tried += (tried.empty() ? "" : ", ") + file;
      continue;
    }
    void* handle = ::dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* e = ::dlerror();
      r.error = "cannot load envkit's OpenImageIO module " + file + ": " + (e ? e : "dlopen failed");
      return r;
    }
    using Entry = ImageBackend* (*)();
    auto entry = reinterpret_cast<Entry>(::dlsym(handle, kOiioEntryPoint));
    if (!entry) {
      r.error = file + " is not envkit's OpenImageIO module of this version (no " + kOiioEntryPoint + ")";
      return r;
    }
    r.backend = entry();
    return r;
  }
  r.error = "envkit's OpenImageIO module is not installed (looked for " + tried + "; set ENVKIT_OIIO_MODULE)";
  return r;
}

}  // namespace

ImageBackend& oiio_backend(const std::string& path) {
  static const Loaded loaded = load();  // thread-safe, once
  if (!loaded.backend) fail(path, "this format needs OpenImageIO: " + loaded.error);
  return *loaded.backend;
}

}  // namespace envkit::detail
