// The _envkit extension: libenv, the probes and the renderer for Python (see
// docs/PYTHON.md). The package envkit (python/envkit/__init__.py) re-exports
// it.
#include <envkit/core/error.h>
#include <envkit/io/request_limits.h>

#include "args.h"
#include "bindings.h"

namespace py = pybind11;

PYBIND11_MODULE(_envkit, m) {
  m.doc() =
      "envkit: environment maps, sampling tables, probes and rendering "
      "(C++ core).";
  // Messages are the one-line "<file>: <problem>" the command-line tools print
  // after their name.
  py::register_exception<envkit::Error>(m, "Error", PyExc_RuntimeError);
  // Refusals Python users catch by their built-in kind: bad argument values as ValueError, files as OSError.
  static const auto argument_error = py::handle(PyErr_NewException(
      "_envkit.ArgumentError", py::make_tuple(m.attr("Error"), py::handle(PyExc_ValueError)).ptr(), nullptr));
  static const auto file_error = py::handle(PyErr_NewException(
      "_envkit.FileError", py::make_tuple(m.attr("Error"), py::handle(PyExc_OSError)).ptr(), nullptr));
  if (!argument_error || !file_error) throw py::error_already_set();
  m.attr("ArgumentError") = argument_error;
  m.attr("FileError") = file_error;
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const envkit::python::ArgumentError& e) {
      PyErr_SetString(argument_error.ptr(), e.what());
    } catch (const envkit::python::FileError& e) {
      PyErr_SetString(file_error.ptr(), e.what());
    }
  });
  // An output too large for memory is a bad argument value; the functions name their argument before this
  // fallback (tried first: translators registered later run first) would see it.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const envkit::RequestTooLarge& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    }
  });
  envkit::python::bind_envmap(m);
  envkit::python::bind_envmap_tools(m);
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
