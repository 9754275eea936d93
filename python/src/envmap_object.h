#pragma once
/// @file envmap_object.h
/// What a Python EnvMap holds: the libenv EnvMap plus what a later write() or
/// resize() needs to know about how it was made (the cube layout it was read or
/// converted with, the filter and source envconvert would record).
#include <envkit/envmap/envmap.h>
#include <envkit/maps/cubemap.h>

#include <optional>
#include <string>

namespace envkit::python {

struct PyEnvMap {
  EnvMap map;
  std::optional<CubeLayout> layout;  ///< cube maps: the layout (from detection or the conversion)
  std::string filter;                ///< recorded as envkit:filter on write (as envconvert does)
  std::string source;                ///< recorded as envkit:source on write
  std::string name = "<array>";      ///< the file it was read from, for messages
};

}  // namespace envkit::python
