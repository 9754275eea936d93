#include "arrays.h"

#include <envkit/error.h>
#include <envkit/image_io.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <memory>
#include <span>

namespace envkit::python {

py::array image_view(const Image& image, py::handle owner) {
  const auto f = static_cast<py::ssize_t>(sizeof(float));
  const py::ssize_t h = image.height, w = image.width, c = image.channels;
  return py::array(py::dtype::of<float>(), {h, w, c}, {w * c * f, c * f, f}, image.pixels.data(), owner);
}

py::array image_array(Image&& image) {
  auto* held = new Image(std::move(image));
  py::capsule owner(held, [](void* p) { delete static_cast<Image*>(p); });
  return image_view(*held, owner);
}

namespace {

/// Keeps a numpy array alive for the C++ image that borrows its floats; the last owner may be a thread that does
/// not hold the GIL (a call that released it), so the reference is dropped under the GIL.
std::shared_ptr<const void> lend(const py::array& array) {
  return std::shared_ptr<const void>(new py::object(array), [](const void* p) {
    py::gil_scoped_acquire gil;
    delete static_cast<const py::object*>(p);
  });
}

}  // namespace

Image image_from_array(const py::array& input, const std::string& path) {
  // float32 (native byte order), C-contiguous, aligned and writable: the image borrows the array's floats; anything
  // else is converted once.
  const bool borrowable = py::isinstance<py::array_t<float>>(input) && (input.flags() & py::array::c_style) &&
                          (input.flags() & py::detail::npy_api::NPY_ARRAY_ALIGNED_) && input.writeable();
  FloatArray a;
  if (borrowable) {
    a = py::reinterpret_borrow<FloatArray>(input);
  } else {
    // A fresh float32 copy (also of a read-only float32 array, which the image's writable view must not alias).
    try {
      a = py::module_::import("numpy").attr("array")(input, py::arg("dtype") = "float32", py::arg("order") = "C",
                                                     py::arg("copy") = true);
    } catch (const py::error_already_set&) {
      fail(path, "expected an array of real numbers");
    }
  }
  if (!a) fail(path, "expected an array of real numbers");
  if (a.ndim() != 2 && a.ndim() != 3)
    fail(path, "expected an H x W x C (or H x W) array, got " + std::to_string(a.ndim()) + " dimensions");
  const int h = static_cast<int>(a.shape(0)), w = static_cast<int>(a.shape(1));
  const int c = a.ndim() == 3 ? static_cast<int>(a.shape(2)) : 1;
  if (h < 1 || w < 1) fail(path, "empty image");
  if (c < 1 || c > 4) fail(path, std::to_string(c) + " channels (envkit handles 1 to 4)");
  const std::size_t n = std::size_t(h) * std::size_t(w) * std::size_t(c);
  if (const std::size_t bad = count_nonfinite(std::span<const float>(a.data(), n)).total(); bad > 0)
    fail(path, std::to_string(bad) + " non-finite values");
  Image image;
  image.width = w;
  image.height = h;
  image.channels = c;
  image.channel_names = default_channel_names(c);
  image.alpha_channel = (c == 2 || c == 4) ? c - 1 : -1;
  // a is the caller's array when borrowable, else the converted copy, which the image then keeps alive instead.
  image.pixels = PixelBuffer::borrow(const_cast<float*>(a.data()), n, lend(a));
  return image;
}

DoubleArray vectors(const py::handle& input, int k, const char* what, std::size_t& count) {
  DoubleArray a = DoubleArray::ensure(input);
  if (!a) throw Error(std::string(what) + ": expected an array of real numbers");
  if (a.ndim() < 1 || a.shape(a.ndim() - 1) != k)
    throw Error(std::string(what) + ": expected an array of shape (..., " + std::to_string(k) + ")");
  count = static_cast<std::size_t>(a.size()) / static_cast<std::size_t>(k);
  return a;
}

std::vector<py::ssize_t> result_shape(const py::array& input, int k_out) {
  std::vector<py::ssize_t> shape(input.shape(), input.shape() + input.ndim() - 1);
  if (k_out > 0) shape.push_back(k_out);
  return shape;
}

Vec3 to_vec3(const py::handle& value, const char* what) {
  const DoubleArray a = DoubleArray::ensure(value);
  if (!a || a.size() != 3) throw Error(std::string(what) + ": expected 3 numbers");
  return Vec3(a.data()[0], a.data()[1], a.data()[2]);
}

py::tuple from_vec3(const Vec3& v) { return py::make_tuple(v.x, v.y, v.z); }

void parallel_chunks(std::size_t n, const std::function<void(std::size_t, std::size_t)>& f) {
  constexpr std::size_t kSerialBelow = 16384;
  if (n < kSerialBelow) {
    f(0, n);
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 8192),
                    [&](const tbb::blocked_range<std::size_t>& r) { f(r.begin(), r.end()); });
}

void warn_clamped(const ClampReport& report, const std::string& path) {
  if (report.any() && PyErr_WarnEx(PyExc_UserWarning, report.message(path).c_str(), 1) != 0)
    throw py::error_already_set();
}

}  // namespace envkit::python
