#pragma once
/// @file arrays.h
/// numpy <-> envkit conversions shared by the bindings: images handed out
/// without a copy (the numpy array keeps the C++ storage alive), direction
/// arrays of any shape (..., 3) read as contiguous doubles, and the "<array>"
/// name under which in-memory inputs appear in error messages.
#include <envkit/core/clamp_report.h>
#include <envkit/core/image.h>
#include <envkit/core/vec.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <string>
#include <vector>

namespace envkit::python {

namespace py = pybind11;

using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

/// (H, W, C) float32 view of `image`'s pixels; `owner` keeps them alive (no
/// copy).
py::array image_view(const Image& image, py::handle owner);
/// Moves `image` into a heap object owned by the returned array (no copy of the
/// pixels).
py::array image_array(Image&& image);
/// An (H, W, C) or (H, W) array (any real dtype, any strides) given as argument `name` as a float image; C in 1..4,
/// names Y/YA/RGB/RGBA, alpha last for 2 and 4 channels. A writable C-contiguous float32 array is not copied: the
/// image borrows its floats (a view: writes show on both sides) and keeps it alive; any other array is converted
/// once. Raises TypeError naming `name` for non-real dtypes, ValueError for bad shapes, non-finite values or an
/// image too large for memory.
Image image_from_array(const py::handle& array, const std::string& name);

/// A (..., K) array of real numbers given as argument `name` as contiguous doubles; `count` receives the number of
/// K-vectors. TypeError / ValueError naming `name` as image_from_array.
DoubleArray vectors(const py::handle& array, int k, const std::string& name, std::size_t& count);
/// Shape of the result for an input of shape (..., K_in) and K_out values per
/// vector (0: drop the axis).
std::vector<py::ssize_t> result_shape(const py::array& input, int k_out);

/// Vec3 from 3 finite real numbers given as argument `name` (TypeError / ValueError naming it otherwise).
Vec3 to_vec3(const py::handle& value, const std::string& name);
py::tuple from_vec3(const Vec3& v);

/// Runs f(begin, end) over [0, n), in parallel (oneTBB) for large n and
/// serially for small ones, so a call on a handful of vectors does not pay for
/// task spawning. Each element is computed independently: results do not depend
/// on the split.
void parallel_chunks(std::size_t n, const std::function<void(std::size_t, std::size_t)>& f);

/// Issues the UserWarning the command-line tools print for values the texel format of `path` clamped (nothing
/// when none was); throws error_already_set when warnings are errors. Needs the GIL.
void warn_clamped(const ClampReport& report, const std::string& path);

}  // namespace envkit::python
