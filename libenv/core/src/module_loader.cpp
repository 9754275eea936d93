#include <dlfcn.h>
#include <envkit/core/module_loader.h>

#include <cstdlib>
#include <filesystem>
#include <vector>

namespace envkit::detail {

void* load_module_entry(const ModuleSpec& spec, std::string& error) {
  std::vector<std::string> candidates;
  if (const char* env = std::getenv(spec.env_variable); env && *env) candidates.emplace_back(env);
  candidates.emplace_back(spec.installed);
  candidates.emplace_back(spec.built);
  std::string tried;
  for (const std::string& file : candidates) {
    std::error_code ec;
    if (!std::filesystem::exists(file, ec)) {
      tried += (tried.empty() ? "" : ", ") + file;
      continue;
    }
    void* handle = ::dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* e = ::dlerror();
      error = std::string("cannot load envkit's ") + spec.what + " module " + file + ": " + (e ? e : "dlopen failed");
      return nullptr;
    }
    void* entry = ::dlsym(handle, spec.entry_point);
    if (!entry)
      error = file + " is not envkit's " + spec.what + " module of this version (no " + spec.entry_point + ")";
    return entry;
  }
  error = std::string("envkit's ") + spec.what + " module is not installed (looked for " + tried + "; set " +
          spec.env_variable + ")";
  return nullptr;
}

}  // namespace envkit::detail
