#include "rotation_arg.h"

#include <envkit/core/error.h>
#include <envkit/maps/convention.h>

#include <cstdio>
#include <string>

#include "args.h"
#include "arrays.h"

namespace envkit::python {

Mat3 rotation_arg(const py::object& r) {
  if (py::isinstance<py::str>(r)) return argument_value([&] { return parse_rotation(r.cast<std::string>()); });
  const DoubleArray a = DoubleArray::ensure(r);
  if (!a || (a.size() != 3 && a.size() != 9))
    throw ArgumentError("rotate: expected 'yaw,pitch,roll', 3 angles in degrees or a 3x3 matrix");
  // Through the tools' text parser, so that validation and results are exactly theirs.
  std::string text;
  char buf[40];
  for (py::ssize_t k = 0; k < a.size(); ++k) {
    std::snprintf(buf, sizeof buf, "%s%.17g", k ? "," : "", a.data()[k]);
    text += buf;
  }
  return argument_value([&] { return parse_rotation(text); });
}

Mat3 rotated(const Mat3& to_world, const py::object& rotate) {
  return rotate.is_none() ? to_world : compose(rotation_arg(rotate), to_world);
}

}  // namespace envkit::python
