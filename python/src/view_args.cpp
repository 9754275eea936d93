#include "view_args.h"

#include <envkit/core/error.h>
#include <envkit/maps/view_spec.h>

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "args.h"
#include "arrays.h"

namespace envkit::python {

namespace {

double number(const py::handle& value, const char* what) {
  double v = 0.0;
  try {
    v = value.cast<double>();
  } catch (const py::cast_error&) {
    throw py::type_error(std::string(what) + ": expected a number");
  }
  if (!std::isfinite(v)) throw ArgumentError(std::string(what) + ": " + std::to_string(v) + " is not finite");
  return v;
}

// envconvert's --view-dir: x,y,z (non-zero) or yaw,pitch in degrees.
Vec3 view_direction(const py::handle& value) {
  std::vector<double> c;
  std::string shown;
  if (py::isinstance<py::str>(value)) {
    shown = value.cast<std::string>();
    std::istringstream in(shown);
    for (std::string item; std::getline(in, item, ',');) {
      try {
        c.push_back(std::stod(item));
      } catch (const std::exception&) {
        throw ArgumentError("view_dir: '" + shown + "' is not x,y,z or yaw,pitch");
      }
    }
  } else {
    const DoubleArray a = DoubleArray::ensure(value);
    if (!a) throw ArgumentError("view_dir: expected x,y,z or yaw,pitch");
    c.assign(a.data(), a.data() + a.size());
    shown = py::str(value).cast<std::string>();
  }
  for (double v : c)
    if (!std::isfinite(v)) throw ArgumentError("view_dir: '" + shown + "' has a non-finite number");
  if (c.size() == 2) return direction_from_yaw_pitch(c[0], c[1]);
  if (c.size() == 3 && Vec3(c[0], c[1], c[2]).length() > 0.0) return Vec3(c[0], c[1], c[2]);
  throw ArgumentError("view_dir: '" + shown + "' is not x,y,z (non-zero) or yaw,pitch");
}

FovAxis fov_axis(const std::string& text) {
  if (text == "h") return FovAxis::Horizontal;
  if (text == "v") return FovAxis::Vertical;
  throw ArgumentError("fov_axis: '" + text + "' is not h or v");
}

}  // namespace

bool ViewArgs::given() const {
  return !view.is_none() || !view_dir.is_none() || !roll.is_none() || !fov.is_none() || !fov_axis.is_none() ||
         !lens.is_none();
}

bool is_view_kind(Kind kind) { return kind == Kind::Perspective || kind == Kind::Fisheye; }

std::optional<ViewParams> view_params(const ViewArgs& args, Kind kind) {
  const std::optional<ViewParams> v = parsed_view(args, kind);
  if (v) check_view(kind, *v);
  return v;
}

std::optional<ViewParams> parsed_view(const ViewArgs& in, Kind kind) {
  if (!in.given()) return std::nullopt;
  ViewArgs a = in;
  if (!in.view.is_none()) {
    if (!in.view_dir.is_none() || !in.roll.is_none() || !in.fov.is_none() || !in.fov_axis.is_none() ||
        !in.lens.is_none())
      throw ArgumentError("view: give either view= or view_dir/roll/fov/fov_axis/lens, not both");
    if (py::isinstance<py::str>(in.view))
      return argument_value([&] { return parse_view(in.view.cast<std::string>()); });
    if (!py::isinstance<py::dict>(in.view))
      throw py::type_error("view: expected a dict (EnvMap.view) or envkit:view text");
    for (const auto& [key, value] : in.view.cast<py::dict>()) {
      const std::string k = py::str(key);
      if (k == "view_dir")
        a.view_dir = py::reinterpret_borrow<py::object>(value);
      else if (k == "roll")
        a.roll = py::reinterpret_borrow<py::object>(value);
      else if (k == "fov")
        a.fov = py::reinterpret_borrow<py::object>(value);
      else if (k == "fov_axis")
        a.fov_axis = py::reinterpret_borrow<py::object>(value);
      else if (k == "lens")
        a.lens = py::reinterpret_borrow<py::object>(value);
      else
        throw ArgumentError("view: unknown key '" + k + "' (view_dir, roll, fov, fov_axis, lens)");
    }
  }
  ViewParams v;
  if (!a.fov.is_none() && py::isinstance<py::sequence>(a.fov) && !py::isinstance<py::str>(a.fov)) {
    // (horizontal, vertical): a perspective view with pixels that need not be square.
    const py::sequence hv = py::reinterpret_borrow<py::sequence>(a.fov);
    if (py::len(hv) != 2) throw ArgumentError("fov: expected degrees or (horizontal, vertical) degrees");
    if (kind != Kind::Perspective) throw ArgumentError("fov: (horizontal, vertical) applies to perspective views");
    v.fov_degrees = number(hv[0], "fov");
    v.fov_v_degrees = number(hv[1], "fov");
    if (!(v.fov_v_degrees > 0.0)) throw ArgumentError("fov: the vertical field of view must be positive");
    if (!a.fov_axis.is_none()) throw ArgumentError("fov_axis: (horizontal, vertical) fov names both axes");
  } else {
    v.fov_degrees = a.fov.is_none() ? default_fov_degrees(kind) : number(a.fov, "fov");
  }
  if (!a.roll.is_none()) {
    v.roll_degrees = number(a.roll, "roll");
    if (std::abs(v.roll_degrees) > 1e6)
      throw ArgumentError("roll: " + std::to_string(v.roll_degrees) + " is outside [-1e6, 1e6]");
  }
  if (!a.fov_axis.is_none()) v.fov_axis = fov_axis(a.fov_axis.cast<std::string>());
  if (!a.lens.is_none()) v.lens = argument_value([&] { return parse_lens(a.lens.cast<std::string>()); });
  if (!a.view_dir.is_none()) v.forward = view_direction(a.view_dir);
  return v;
}

py::dict view_dict(const ViewParams& v) {
  py::dict d;
  d["view_dir"] = from_vec3(v.forward);
  d["roll"] = v.roll_degrees;
  d["fov"] = v.fov_v_degrees > 0.0 ? py::object(py::make_tuple(v.fov_degrees, v.fov_v_degrees))
                                   : py::object(py::float_(v.fov_degrees));
  d["fov_axis"] = v.fov_axis == FovAxis::Vertical ? "v" : "h";
  d["lens"] = lens_name(v.lens);
  return d;
}

}  // namespace envkit::python
