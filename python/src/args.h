#pragma once
/// @file args.h
/// Checked conversions of the arguments of every function of the module. Each raises TypeError for a value of the
/// wrong type and ValueError for a value out of range, both naming the argument ("size: expected an integer, got
/// float 8.5", "size: 1099511627776 is outside [0, 262144]"), instead of pybind11's own conversion errors, which
/// name no argument, wrap around, or drop the imaginary part of complex numbers.
#include <envkit/core/error.h>
#include <envkit/io/request_limits.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <functional>
#include <optional>
#include <string>
#include <utility>

namespace envkit::python {

namespace py = pybind11;

/// A refused argument value (an unknown name, a bad combination): raised in Python as envkit.ArgumentError, both an
/// envkit.Error and a ValueError.
class ArgumentError : public Error {
 public:
  using Error::Error;
};

/// A file that cannot be read, parsed or written: raised in Python as envkit.FileError, both an envkit.Error and an
/// OSError.
class FileError : public Error {
 public:
  using Error::Error;
};

/// f(), with the library's refusals (envkit::Error) turned into E: the parse of a name (ArgumentError) or a file
/// operation (FileError). Requests too large for memory stay ValueErrors; refusals already typed pass through.
template <class E, class F>
auto rethrown_as(F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const ArgumentError&) {
    throw;
  } catch (const FileError&) {
    throw;
  } catch (const RequestTooLarge&) {
    throw;
  } catch (const Error& e) {
    throw E(e.what());
  }
}
template <class F>
auto argument_value(F&& f) -> decltype(f()) {
  return rethrown_as<ArgumentError>(std::forward<F>(f));
}
template <class F>
auto file_operation(F&& f) -> decltype(f()) {
  return rethrown_as<FileError>(std::forward<F>(f));
}

/// The largest natural size N any size argument accepts, so that every image side computed from it fits in an int;
/// whether the image it makes fits in memory (every larger one would not) is check_size_arg's question.
inline constexpr long long kMaxSizeArg = 1 << 20;

/// A Python int (or numpy integer; not bool, not float) in [lo, hi].
long long integer_arg(const py::handle& value, const std::string& name, long long lo, long long hi);
inline int int_arg(const py::handle& value, const std::string& name, int lo, int hi) {
  return static_cast<int>(integer_arg(value, name, lo, hi));
}
/// None -> nullopt, else int_arg.
std::optional<int> optional_int_arg(const py::handle& value, const std::string& name, int lo, int hi);
/// A sequence of two integers in [lo, hi], e.g. size=(width, height).
std::pair<int, int> int_pair_arg(const py::handle& value, const std::string& name, int lo, int hi);

/// A real number (int, float or numpy scalar; not complex, not str) in [lo, hi]; NaN is refused with ValueError.
double real_arg(const py::handle& value, const std::string& name, double lo, double hi);
/// None -> nullopt, else real_arg.
std::optional<double> optional_real_arg(const py::handle& value, const std::string& name, double lo, double hi);

/// Any array-like of real numbers (bool, integer or floating dtype) as a numpy array, in any layout (strided views
/// included; nothing is copied here). TypeError for complex, object, string and other dtypes, and for values
/// numpy cannot make an array of.
py::array real_array(const py::handle& value, const std::string& name);

/// Runs one of libenv's request checks (request_limits.h) for argument `name`; its RequestTooLarge is raised as
/// ValueError("<name>: <message>"). Needs no GIL.
void check_request_arg(const std::string& name, const std::function<void()>& check);
/// check_request_arg of envkit::check_request_size for an output of width x height texels
/// ("size: <what> of W x H needs about X GiB of memory; ...").
void check_size_arg(const std::string& name, const std::string& what, long long width, long long height,
                    double bytes_per_texel);

}  // namespace envkit::python
