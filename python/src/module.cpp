// The _envkit extension: libenv, the probes and the renderer for Python (see
// docs/PYTHON.md). The package envkit (python/envkit/__init__.py) re-exports
// it.
#include <envkit/error.h>

#include "bindings.h"

namespace py = pybind11;

PYBIND11_MODULE(_envkit, m) {
  m.doc() =
      "envkit: environment maps, sampling tables, probes and rendering "
      "(C++ core).";
  // Messages are the one-line "<file>: <problem>" the command-line tools print
  // after their name.
  py::register_exception<envkit::Error>(m, "Error", PyExc_RuntimeError);
  envkit::python::bind_envmap(m);
  envkit::python::bind_tables(m);
  envkit::python::bind_ibl(m);
  envkit::python::bind_merge(m);
  py::module_ probes = m.def_submodule("probes", "Analytic environments with closed-form power (probes.h).");
  envkit::python::bind_probes(probes);
#ifdef ENVKIT_PY_RENDER
  envkit::python::bind_render(m);
  m.attr("has_renderer") = true;
#else
  m.attr("has_renderer") = false;
#endif
}
