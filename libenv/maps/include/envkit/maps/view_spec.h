#pragma once
/// @file view_spec.h
/// The parameterization spec of a camera view output (perspective, fisheye) as envconvert builds it from
/// --size, --aspect and the view options, so that every caller (the tool, the Python module) gets the same image
/// size and defaults.
#include <envkit/maps/convention.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/parameterization.h>
#include <envkit/maps/view.h>

namespace envkit {

/// The field of view a view of `kind` gets when none is given: 180 degrees for a fisheye (a half-sphere lens),
/// 90 for a perspective view.
double default_fov_degrees(Kind kind);

/// Spec of a `kind` view (Perspective or Fisheye) `width` texels wide and max(1, round(width / aspect)) high,
/// looking as `view` says; grid and basis from `conv` as spec_for gives them. Throws Error for aspect <= 0 or a
/// kind that is not a view.
ParamSpec view_spec(Kind kind, int width, double aspect, const ViewParams& view, const Convention& conv);

/// Throws Error (the parameterization's message) when `view` is not valid for `kind` (a field of view out of the
/// lens's range, ...), before any image of that size is made.
void check_view(Kind kind, const ViewParams& view);

}  // namespace envkit
