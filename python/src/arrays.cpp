#include "arrays.h"

#include <envkit/error.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

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

Image image_from_array(const py::array& input, const std::string& path) {
  const FloatArray a = FloatArray::ensure(input);
  if (!a) fail(path, "expected an array of real numbers");
  if (a.ndim() != 2 && a.ndim() != 3)
    fail(path, "expected an H x W x C (or H x W) array, got " + std::to_string(a.ndim()) + " dimensions");
  const int h = static_cast<int>(a.shape(0)), w = static_cast<int>(a.shape(1));
  const int c = a.ndim() == 3 ? static_cast<int>(a.shape(2)) : 1;
  if (h < 1 || w < 1) fail(path, "empty image");
  if (c < 1 || c > 4) fail(path, std::to_string(c) + " channels (envkit handles 1 to 4)");
  Image image(w, h, c);
  image.channel_names = default_channel_names(c);
  image.alpha_channel = (c == 2 || c == 4) ? c - 1 : -1;
  const float* src = a.data();
  std::size_t nonfinite = 0;
  for (std::size_t k = 0; k < image.pixels.size(); ++k) {
    image.pixels[k] = src[k];
    nonfinite += std::isfinite(src[k]) ? 0 : 1;
  }
  if (nonfinite > 0) fail(path, std::to_string(nonfinite) + " non-finite values");
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

}  // namespace envkit::python
