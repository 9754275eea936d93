#include "arrays.h"

#include <envkit/core/error.h>
#include <envkit/io/image_io.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <memory>
#include <span>

#include "args.h"

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

Image image_from_array(const py::handle& value, const std::string& name) {
  const py::array input = real_array(value, name);
  if (input.ndim() != 2 && input.ndim() != 3)
    throw py::value_error(name + ": expected an H x W x C (or H x W) array, got " + std::to_string(input.ndim()) +
                          " dimensions");
  const py::ssize_t h = input.shape(0), w = input.shape(1), c = input.ndim() == 3 ? input.shape(2) : 1;
  if (h < 1 || w < 1) throw py::value_error(name + ": empty image");
  if (c < 1 || c > 4) throw py::value_error(name + ": " + std::to_string(c) + " channels (envkit handles 1 to 4)");
  // A strided or broadcast view may be far larger than the memory behind it: its float copy is checked first.
  check_size_arg(name, "an image", w, h, double(c) * sizeof(float));
  // float32 (native byte order), C-contiguous, aligned and writable: the image borrows the array's floats; anything
  // else (other dtypes, strided views, read-only arrays, which the image's writable view must not alias) is
  // converted once into a fresh float32 copy.
  const bool borrowable = py::isinstance<py::array_t<float>>(input) && (input.flags() & py::array::c_style) &&
                          (input.flags() & py::detail::npy_api::NPY_ARRAY_ALIGNED_) && input.writeable();
  const FloatArray a = borrowable
                           ? py::reinterpret_borrow<FloatArray>(input)
                           : FloatArray(py::module_::import("numpy").attr("array")(
                                 input, py::arg("dtype") = "float32", py::arg("order") = "C", py::arg("copy") = true));
  const std::size_t n = std::size_t(h) * std::size_t(w) * std::size_t(c);
  if (const std::size_t bad = count_nonfinite(std::span<const float>(a.data(), n)).total(); bad > 0)
    throw py::value_error(name + ": " + std::to_string(bad) + " non-finite values");
  Image image;
  image.width = static_cast<int>(w);
  image.height = static_cast<int>(h);
  image.channels = static_cast<int>(c);
  image.channel_names = default_channel_names(image.channels);
  image.alpha_channel = (c == 2 || c == 4) ? image.channels - 1 : -1;
  // a is the caller's array when borrowable, else the converted copy, which the image then keeps alive instead.
  image.pixels = PixelBuffer::borrow(const_cast<float*>(a.data()), n, lend(a));
  return image;
}

DoubleArray vectors(const py::handle& value, int k, const std::string& name, std::size_t& count) {
  const py::array input = real_array(value, name);
  if (input.ndim() < 1 || input.shape(input.ndim() - 1) != k)
    throw py::value_error(name + ": expected an array of shape (..., " + std::to_string(k) + ")");
  count = static_cast<std::size_t>(input.size()) / static_cast<std::size_t>(k);
  // The contiguous double copy (and the caller's result of about as many bytes) of a possibly broadcast view.
  check_size_arg(name, "an array of vectors", static_cast<long long>(count), 1, 2.0 * k * sizeof(double));
  return DoubleArray::ensure(input);
}

std::vector<py::ssize_t> result_shape(const py::array& input, int k_out) {
  std::vector<py::ssize_t> shape(input.shape(), input.shape() + input.ndim() - 1);
  if (k_out > 0) shape.push_back(k_out);
  return shape;
}

Vec3 to_vec3(const py::handle& value, const std::string& name) {
  const py::array input = real_array(value, name);
  if (input.size() != 3) throw py::value_error(name + ": expected 3 numbers");
  const DoubleArray a = DoubleArray::ensure(input);
  const Vec3 v(a.data()[0], a.data()[1], a.data()[2]);
  if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
    throw py::value_error(name + ": expected 3 finite numbers");
  return v;
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
