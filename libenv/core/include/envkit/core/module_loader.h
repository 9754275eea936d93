#pragma once
// Loads one of envkit's own modules (shared objects opened with dlopen on first need), so that a run which never
// meets an OIIO format or a HEALPix map never loads those libraries and their dependencies at start-up.
#include <string>

namespace envkit::detail {

/// Where a module is looked for and what it exports.
struct ModuleSpec {
  const char* what;          ///< for messages: "OpenImageIO", "HEALPix"
  const char* env_variable;  ///< a path that overrides the others when set, e.g. "ENVKIT_OIIO_MODULE"
  const char* installed;     ///< the installed copy
  const char* built;         ///< the build tree's copy
  const char* entry_point;   ///< the extern "C" symbol; its name carries the interface version
};

/// The entry point's address, or nullptr with `error` saying why (not installed, not loadable, another version).
void* load_module_entry(const ModuleSpec& spec, std::string& error);

}  // namespace envkit::detail
