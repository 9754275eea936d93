#pragma once
/// @file rotation_arg.h
/// The rotate= argument of the bindings, read as the tools' --rotate reads its text.
#include <envkit/core/vec.h>
#include <pybind11/pybind11.h>

namespace envkit::python {

/// Rotation from "yaw,pitch,roll", 9 row-major numbers, a 3-sequence of degrees or a 3x3 matrix (the tools'
/// --rotate, parse_rotation: matrices must be rotations within 1e-4).
Mat3 rotation_arg(const pybind11::object& r);

/// `to_world` with `rotate` (None: unchanged) applied on top, as the tools' --rotate does on a freshly read map.
Mat3 rotated(const Mat3& to_world, const pybind11::object& rotate);

}  // namespace envkit::python
