#include "args.h"

#include <envkit/io/request_limits.h>

#include <cmath>
#include <cstdio>

namespace envkit::python {

namespace {

/// "float 8.5", "str 'a'", "NoneType": the type and (short) value of what was given.
std::string given(const py::handle& value) {
  std::string text = py::str(py::repr(value));
  if (text.size() > 40) text = text.substr(0, 37) + "...";
  const std::string type = py::str(value.get_type().attr("__name__"));
  return value.is_none() ? type : type + " " + text;
}

std::string number_text(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

[[noreturn]] void out_of_range(const std::string& name, const std::string& value, const std::string& lo,
                               const std::string& hi) {
  throw py::value_error(name + ": " + value + " is outside [" + lo + ", " + hi + "]");
}

}  // namespace

long long integer_arg(const py::handle& value, const std::string& name, long long lo, long long hi) {
  // Python ints and numpy integers implement __index__; floats (even 8.0), str and bool are refused.
  if (PyBool_Check(value.ptr()) || !PyIndex_Check(value.ptr()))
    throw py::type_error(name + ": expected an integer, got " + given(value));
  const py::int_ i = py::reinterpret_steal<py::int_>(PyNumber_Index(value.ptr()));
  if (!i) throw py::error_already_set();
  int overflow = 0;
  const long long v = PyLong_AsLongLongAndOverflow(i.ptr(), &overflow);
  if (overflow != 0 || v < lo || v > hi)
    out_of_range(name, py::str(py::object(i)).cast<std::string>(), std::to_string(lo), std::to_string(hi));
  return v;
}

std::optional<int> optional_int_arg(const py::handle& value, const std::string& name, int lo, int hi) {
  if (value.is_none()) return std::nullopt;
  return int_arg(value, name, lo, hi);
}

std::pair<int, int> int_pair_arg(const py::handle& value, const std::string& name, int lo, int hi) {
  if (!py::isinstance<py::sequence>(value) || py::isinstance<py::str>(value) || py::len(value) != 2)
    throw py::type_error(name + ": expected two integers, got " + given(value));
  const py::sequence s = py::reinterpret_borrow<py::sequence>(value);
  return {int_arg(s[0], name, lo, hi), int_arg(s[1], name, lo, hi)};
}

double real_arg(const py::handle& value, const std::string& name, double lo, double hi) {
  // Python ints and floats, numpy integer and floating scalars; complex numbers, str and None are refused.
  const bool numpy_real = py::hasattr(value, "dtype") && py::hasattr(value.attr("dtype"), "kind") &&
                          py::str(value.attr("dtype").attr("kind")).cast<std::string>() == "f";
  if (!(PyFloat_Check(value.ptr()) || PyIndex_Check(value.ptr()) || numpy_real))
    throw py::type_error(name + ": expected a real number, got " + given(value));
  const double x = PyFloat_AsDouble(value.ptr());
  if (x == -1.0 && PyErr_Occurred()) {  // an int too large for a double
    PyErr_Clear();
    out_of_range(name, py::str(value).cast<std::string>(), number_text(lo), number_text(hi));
  }
  if (!(x >= lo && x <= hi)) out_of_range(name, number_text(x), number_text(lo), number_text(hi));
  return x;
}

std::optional<double> optional_real_arg(const py::handle& value, const std::string& name, double lo, double hi) {
  if (value.is_none()) return std::nullopt;
  return real_arg(value, name, lo, hi);
}

py::array real_array(const py::handle& value, const std::string& name) {
  if (value.is_none() || py::isinstance<py::str>(value) || py::isinstance<py::bytes>(value))
    throw py::type_error(name + ": expected an array of real numbers, got " + given(value));
  py::array a;
  try {
    a = py::module_::import("numpy").attr("asarray")(value);
  } catch (const py::error_already_set&) {
    throw py::type_error(name + ": expected an array of real numbers, got " + given(value));
  }
  const char kind = a.dtype().kind();
  if (kind != 'b' && kind != 'i' && kind != 'u' && kind != 'f')
    throw py::type_error(name + ": expected an array of real numbers, got dtype " +
                         py::str(a.dtype()).cast<std::string>());
  return a;
}

void check_request_arg(const std::string& name, const std::function<void()>& check) {
  try {
    check();
  } catch (const RequestTooLarge& e) {
    throw py::value_error(name + ": " + e.what());
  }
}

void check_size_arg(const std::string& name, const std::string& what, long long width, long long height,
                    double bytes_per_texel) {
  check_request_arg(name, [&] { check_request_size(what, width, height, bytes_per_texel); });
}

}  // namespace envkit::python
