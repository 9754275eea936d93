#include <envkit/core/error.h>
#include <envkit/maps/view.h>

#include <algorithm>
#include <cctype>
#include <sstream>
#include <vector>

namespace envkit {

std::string lens_name(Lens lens) {
  switch (lens) {
    case Lens::Equidistant:
      return "equidistant";
    case Lens::Equisolid:
      return "equisolid";
    case Lens::Orthographic:
      return "orthographic";
    case Lens::Stereographic:
      return "stereographic";
  }
  return "unknown";
}

Lens parse_lens(const std::string& name) {
  std::string n = name;
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (n == "equidistant" || n == "equi-distant") return Lens::Equidistant;
  if (n == "equisolid" || n == "equal-area" || n == "equisolid-angle") return Lens::Equisolid;
  if (n == "orthographic" || n == "ortho") return Lens::Orthographic;
  if (n == "stereographic" || n == "stereo") return Lens::Stereographic;
  throw Error("unknown lens '" + name + "' (expected equidistant, equisolid, orthographic or stereographic)");
}

ViewBasis view_basis(const ViewParams& view) {
  const double len = view.forward.length();
  if (!(len > 0.0) || !std::isfinite(len)) throw Error("a view direction must be a finite non-zero vector");
  ViewBasis b;
  b.forward = view.forward / len;
  // Image up: world +Y made perpendicular to forward; straight up or down there
  // is no such part, so the horizon's reference is -Z (looking up) or +Z
  // (looking down), continuous with a pitch just short of 90.
  Vec3 up = Vec3(0, 1, 0) - b.forward.y * b.forward;
  if (up.length() < 1e-9) up = b.forward.y > 0 ? Vec3(0, 0, -1) : Vec3(0, 0, 1);
  up.normalize();
  Vec3 right = (b.forward % up).normalized();
  const double r = view.roll_degrees * kPi / 180.0;
  // Camera turned counter-clockwise by r about forward: its up leans towards
  // its former left (-right).
  b.up = (std::cos(r) * up - std::sin(r) * right).normalized();
  b.right = (b.forward % b.up).normalized();
  return b;
}

Vec3 direction_from_yaw_pitch(double yaw_degrees, double pitch_degrees) {
  const double y = yaw_degrees * kPi / 180.0, p = pitch_degrees * kPi / 180.0;
  return Vec3(std::sin(y) * std::cos(p), std::sin(p), std::cos(y) * std::cos(p));
}

std::string format_view(const ViewParams& v) {
  std::ostringstream s;
  s.precision(17);
  s << "forward=" << v.forward.x << "," << v.forward.y << "," << v.forward.z << ";roll=" << v.roll_degrees
    << ";fov=" << v.fov_degrees << ";axis=" << (v.fov_axis == FovAxis::Horizontal ? "h" : "v")
    << ";lens=" << lens_name(v.lens);
  if (v.fov_v_degrees > 0.0) s << ";vfov=" << v.fov_v_degrees;
  return s.str();
}

namespace {
double number(const std::string& field, const std::string& text) {
  try {
    std::size_t used = 0;
    const double v = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(v)) throw std::invalid_argument(text);
    return v;
  } catch (const std::exception&) {
    throw Error("view " + field + " '" + text + "' is not a number");
  }
}
}  // namespace

ViewParams parse_view(const std::string& text) {
  ViewParams v;
  std::istringstream in(text);
  for (std::string item; std::getline(in, item, ';');) {
    const auto eq = item.find('=');
    if (eq == std::string::npos) throw Error("view field '" + item + "' is not key=value");
    const std::string key = item.substr(0, eq), value = item.substr(eq + 1);
    if (key == "forward") {
      std::vector<double> c;
      std::istringstream cs(value);
      for (std::string x; std::getline(cs, x, ',');) c.push_back(number("forward", x));
      if (c.size() != 3) throw Error("view forward '" + value + "' needs 3 numbers");
      v.forward = Vec3(c[0], c[1], c[2]);
    } else if (key == "roll") {
      v.roll_degrees = number("roll", value);
    } else if (key == "fov") {
      v.fov_degrees = number("fov", value);
    } else if (key == "axis") {
      if (value != "h" && value != "v") throw Error("view axis '" + value + "' is neither h nor v");
      v.fov_axis = value == "h" ? FovAxis::Horizontal : FovAxis::Vertical;
    } else if (key == "vfov") {
      v.fov_v_degrees = number("vfov", value);
    } else if (key == "lens") {
      v.lens = parse_lens(value);
    } else {
      throw Error("unknown view field '" + key + "'");
    }
  }
  view_basis(v);  // validates forward
  return v;
}

}  // namespace envkit
