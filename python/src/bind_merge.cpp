// envkit.merge: envmerge from Python. Partial captures (fisheye photographs, mirror balls, perspective views,
// maps) merged into one lat-long by libenv's merge_captures, the call envmerge makes, so the result is
// envmerge's bit for bit.
#include <envkit/core/error.h>
#include <envkit/envmap/merge.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/latlong.h>
#include <pybind11/stl.h>

#include <memory>

#include "args.h"
#include "arrays.h"
#include "bindings.h"
#include "envmap_object.h"
#include "rotation_arg.h"

namespace envkit::python {

namespace {

/// One capture: an EnvMap, or a dict(map=EnvMap, exposure=X, mask=array or path, rotate=R) (envmerge's
/// FILE@exposure=...,mask=...,rotate=...; the view and parameterization belong to the EnvMap).
Capture capture_of(const py::handle& item) {
  py::object map_obj = py::reinterpret_borrow<py::object>(item);
  py::object exposure = py::none(), mask = py::none(), rotate = py::none();
  if (py::isinstance<py::dict>(item)) {
    map_obj = py::none();
    for (const auto& [key, value] : item.cast<py::dict>()) {
      const std::string k = py::str(key);
      const auto v = py::reinterpret_borrow<py::object>(value);
      if (k == "map")
        map_obj = v;
      else if (k == "exposure")
        exposure = v;
      else if (k == "mask")
        mask = v;
      else if (k == "rotate")
        rotate = v;
      else
        throw ArgumentError("merge: unknown capture key '" + k + "' (map, exposure, mask, rotate)");
    }
  }
  if (!py::isinstance<PyEnvMap>(map_obj))
    throw py::type_error("merge: a capture is an EnvMap or a dict with map=EnvMap");
  const PyEnvMap& p = map_obj.cast<const PyEnvMap&>();
  Capture c;
  // merge_captures takes its captures by value: one copy of the pixels.
  c.map = EnvMap{p.map.image, p.map.param->clone(), p.map.convention, p.map.rotation};
  if (!rotate.is_none()) c.map.rotation = rotation_arg(rotate);  // envmerge's rotate= replaces the rotation
  c.name = p.name;
  if (!exposure.is_none()) {
    c.exposure = real_arg(exposure, "exposure", 0.0, 1e30);
    if (!(c.exposure > 0.0)) throw py::value_error("exposure: must be positive (capture " + c.name + ")");
  }
  if (py::isinstance<py::str>(mask))
    c.mask = read_image(mask.cast<std::string>());
  else if (!mask.is_none())
    c.mask = image_from_array(mask, "mask");
  return c;
}

/// Bytes per texel of a merge, as envmerge's --size check counts them.
constexpr double kMergeBytesPerTexel = 40.0;

}  // namespace

void bind_merge(py::module_& m) {
  m.def(
      "merge",
      [](const py::sequence& items, const py::object& size_arg) {
        // envmerge --size: the merged lat-long is 2N x N, RGBA plus per-capture weights.
        const int size = int_arg(size_arg, "size", 1, 1 << 15);
        check_size_arg("size", "merged lat-long", 2LL * size, size, kMergeBytesPerTexel);
        std::vector<Capture> captures;
        for (const py::handle item : items) captures.push_back(capture_of(item));
        auto out = std::make_shared<PyEnvMap>();
        MergeReport report;
        {
          py::gil_scoped_release release;
          const LatLongMap dst(2 * size, size);
          out->map.image = merge_captures(captures, dst, identity3(), &report);
          out->map.param = dst.clone();
        }
        // As envmerge writes it: the captures' envkit:* keys describe other files.
        std::erase_if(out->map.image.metadata, [](const auto& kv) { return kv.first.rfind("envkit:", 0) == 0; });
        out->filter = "area";
        out->source = "envmerge of " + std::to_string(captures.size()) + " captures";
        py::dict r;
        r["uncovered_sr"] = report.uncovered_solid_angle;
        r["uncovered_percent"] = 100.0 * report.uncovered_solid_angle / kFourPi;
        py::list caps;
        for (std::size_t k = 0; k < captures.size(); ++k) {
          py::dict c;
          c["file"] = captures[k].name;
          c["covered_sr"] = report.covered_solid_angle[k];
          c["weight_share"] = report.weight_share[k];
          caps.append(c);
        }
        r["captures"] = caps;
        return py::make_tuple(out, r);
      },
      py::arg("captures"), py::arg("size") = 512,
      R"(envmerge: merges partial captures into a 2N x N lat-long (RGBA, alpha 0 where no capture sees). Each
capture is an EnvMap (its parameterization and view as read, e.g. EnvMap(path, 'fisheye', view=...)) or a dict
map=EnvMap, exposure=X, mask=array or path (0 drops a pixel), rotate=R. Returns (EnvMap, report) with report as
envmerge --json prints it (uncovered_sr, uncovered_percent, captures: file, covered_sr, weight_share).)");
}

}  // namespace envkit::python
