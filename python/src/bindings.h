#pragma once
/// @file bindings.h
/// The parts of the _envkit extension, one function per file.
#include <pybind11/pybind11.h>

namespace envkit::python {

void bind_envmap(pybind11::module_& m);
void bind_tables(pybind11::module_& m);
void bind_probes(pybind11::module_& m);
/// After bind_envmap: adds methods to EnvMap.
void bind_ibl(pybind11::module_& m);
/// After bind_envmap: adds the skylibs-style methods to EnvMap (bind_envmap_tools.cpp).
void bind_envmap_tools(pybind11::module_& m);
void bind_merge(pybind11::module_& m);
/// Defined only when the renderer is built (ENVKIT_PY_RENDER).
void bind_render(pybind11::module_& m);

}  // namespace envkit::python
