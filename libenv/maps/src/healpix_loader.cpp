// Loads envkit's HEALPix module (healpix_geometry.h) on first need.
#include <envkit/core/error.h>
#include <envkit/core/module_loader.h>

#include <string>

#include "healpix_geometry.h"

namespace envkit::detail {
namespace {

using Factory = HealpixGeometry* (*)(int);

struct Loaded {
  Factory factory = nullptr;
  std::string error;
};

Loaded load() {
  const ModuleSpec spec{"HEALPix", "ENVKIT_HEALPIX_MODULE", ENVKIT_HEALPIX_MODULE_INSTALL, ENVKIT_HEALPIX_MODULE_BUILD,
                        kHealpixEntryPoint};
  Loaded r;
  if (void* entry = load_module_entry(spec, r.error)) r.factory = reinterpret_cast<Factory>(entry);
  return r;
}

}  // namespace

std::shared_ptr<const HealpixGeometry> healpix_geometry(int nside) {
  static const Loaded loaded = load();  // thread-safe, once
  if (!loaded.factory) throw Error("HEALPix maps need " + loaded.error);
  return std::shared_ptr<const HealpixGeometry>(loaded.factory(nside));
}

}  // namespace envkit::detail
