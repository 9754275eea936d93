#pragma once
/// @file view_args.h
/// Camera-view arguments of the bindings (perspective and fisheye maps): the options envconvert takes
/// (--view-dir, --roll, --fov, --fov-axis, --lens) as keywords, or all of them at once as `view=` (the dict
/// EnvMap.view returns, or the envkit:view metadata text), turned into libenv's ViewParams.
#include <envkit/maps/parameterization.h>
#include <envkit/maps/view.h>
#include <pybind11/pybind11.h>

#include <optional>

namespace envkit::python {

namespace py = pybind11;

struct ViewArgs {
  py::object view = py::none();      ///< dict (keys below) or "forward=...;roll=...;..." text
  py::object view_dir = py::none();  ///< (x, y, z), (yaw, pitch) in degrees, or the text "x,y,z" / "yaw,pitch"
  py::object roll = py::none();      ///< degrees
  py::object fov = py::none();       ///< degrees (default: default_fov_degrees of the kind)
  py::object fov_axis = py::none();  ///< "h" or "v"
  py::object lens = py::none();      ///< fisheye lens name
  bool given() const;
};

/// The view the arguments describe for a map of `kind`, or nullopt when none was given. Defaults as envconvert's
/// (fov from default_fov_degrees); validated by libenv (check_view). Throws envkit::Error naming the argument.
std::optional<ViewParams> view_params(const ViewArgs& args, Kind kind);
/// The same without the check: for a ConversionRequest, which validate() checks.
std::optional<ViewParams> parsed_view(const ViewArgs& args, Kind kind);

/// The view as a dict of the keywords above (view_dir as x, y, z), so that it can be passed back as view=.
py::dict view_dict(const ViewParams& view);

bool is_view_kind(Kind kind);

}  // namespace envkit::python
