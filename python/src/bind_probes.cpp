// envkit.probes: the analytic environments of probes.h (closed-form power) and
// their exact rasterization into any parameterization, as envprobe does.
#include <envkit/core/error.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/param_factory.h>
#include <envkit/probes.h>
#include <pybind11/stl.h>

#include <memory>

#include "args.h"
#include "arrays.h"
#include "bindings.h"
#include "envmap_object.h"

namespace envkit::python {

namespace {

/// Checker cells along each axis: more than texels of any map envkit makes would only alias.
constexpr int kMaxCheckerCells = 1 << 16;

using probes::Probe;

/// A radiance argument: 3 finite numbers >= 0 (probes::valid_radiance), else ValueError naming it.
Vec3 radiance_arg(const py::handle& value, const std::string& name) {
  const Vec3 v = to_vec3(value, name);
  if (!probes::valid_radiance(v)) throw py::value_error(name + ": a radiance must be finite and >= 0");
  return v;
}
using ProbePtr = std::shared_ptr<Probe>;

py::array radiance(const Probe& p, const py::object& input) {
  std::size_t n = 0;
  const DoubleArray in = vectors(input, 3, "directions", n);
  py::array_t<double> out(result_shape(in, 3));
  const double* d = in.data();
  double* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    parallel_chunks(n, [&](std::size_t k0, std::size_t k1) {
      for (std::size_t k = k0; k < k1; ++k) {
        Vec3 dir(d[3 * k], d[3 * k + 1], d[3 * k + 2]);
        const double len = dir.length();
        const Vec3 l = len > 0.0 && std::isfinite(len) ? p.radiance(dir / len) : Vec3(0, 0, 0);
        o[3 * k] = l.x, o[3 * k + 1] = l.y, o[3 * k + 2] = l.z;
      }
    });
  }
  return out;
}

/// Bytes per texel of a rasterized probe, as envprobe's --size check counts them.
constexpr double kRasterBytesPerTexel = 48.0;

std::shared_ptr<PyEnvMap> rasterize(const Probe& probe, const std::string& to, const py::object& size_arg,
                                    const std::string& convention, const std::optional<std::string>& layout,
                                    bool alpha) {
  const int size = int_arg(size_arg, "size", 1, int(kMaxSizeArg));
  const Convention& conv = argument_value([&]() -> const Convention& { return envkit::convention(convention); });
  const Kind kind = argument_value([&] { return parse_kind(to); });
  std::optional<CubeLayout> l;
  if (layout && kind == Kind::CubeMap) l = argument_value([&] { return parse_layout(*layout); });
  const ParamSpec spec = spec_for(kind, size, conv, l);
  check_size_arg("size", kind_name(kind) + " map", spec.width, spec.height, kRasterBytesPerTexel);
  auto out = std::make_shared<PyEnvMap>();
  {
    py::gil_scoped_release release;
    const auto map = make_parameterization(spec);
    probes::RasterOptions options;
    options.map_to_world = conv.frame(kind);
    // Maps with texels that hold no data (mirror ball corners, blank cross
    // cells) get a coverage channel.
    bool uncovered = false;
    for (int j = 0; j < map->height() && !uncovered; ++j)
      for (int i = 0; i < map->width() && !uncovered; ++i) uncovered = !(map->texel_solid_angle(i, j) > 0.0);
    options.alpha = alpha || uncovered;
    out->map.image = probes::rasterize(probe, *map, options);
    out->map.param = map->clone();
    out->map.convention = conv.name;
  }
  if (kind == Kind::CubeMap) out->layout = l ? *l : conv.cube_layout;
  out->name = "<probe>";
  out->map.image.metadata["envkit:probe"] = probe.describe();
  return out;
}

}  // namespace

void bind_probes(py::module_& m) {
  py::class_<Probe, ProbePtr>(m, "Probe",
                              R"(An analytic environment (probes.h): radiance per direction (world frame,
+Y up, linear RGB) with a closed-form total power. rasterize() writes it into any parameterization with each
texel the exact average over its solid angle (small features such as a sun keep their flux exactly).)")
      .def("describe", &Probe::describe)
      .def("__repr__", [](const Probe& p) { return "<envkit.probes.Probe " + p.describe() + ">"; })
      .def("radiance", &radiance, py::arg("directions"), "Radiance at directions (..., 3) -> (..., 3) float64.")
      .def(
          "total_power", [](const Probe& p) { return from_vec3(p.total_power()); },
          "Integral of L over the sphere per channel.")
      .def_property_readonly("power_is_closed_form", &Probe::power_is_closed_form)
      .def(
          "upward_irradiance",
          [](const Probe& p) -> py::object {
            const auto e = p.upward_irradiance();
            if (!e) return py::none();
            return from_vec3(*e);
          },
          "Irradiance on a plane facing +Y when it has a closed form, else "
          "None.")
      .def("rasterize", &rasterize, py::arg("to") = "latlong", py::arg("size") = 512, py::arg("convention") = "envkit",
           py::arg("layout") = py::none(), py::arg("alpha") = false,
           "An EnvMap of the probe at natural size N (envprobe KIND -o OUT "
           "--to TO --size ...).");

  m.def(
      "constant",
      [](const py::object& radiance) -> ProbePtr {
        return std::make_shared<probes::ConstantProbe>(radiance_arg(radiance, "radiance"));
      },
      py::arg("radiance"), "L = radiance everywhere; power 4 pi L.");
  m.def(
      "gradient",
      [](const py::object& base, const py::object& gain, const std::string& form) -> ProbePtr {
        probes::GradientProbe::Form f;
        if (form == "upper")
          f = probes::GradientProbe::Form::UpperLinear;
        else if (form == "quadratic")
          f = probes::GradientProbe::Form::Quadratic;
        else
          throw ArgumentError("gradient: form '" + form + "' (expected upper or quadratic)");
        return std::make_shared<probes::GradientProbe>(to_vec3(base, "base"), to_vec3(gain, "gain"), f);
      },
      py::arg("base"), py::arg("gain"), py::arg("form") = "upper",
      "L = base + gain max(y, 0) (upper) or base + gain y^2 "
      "(quadratic).");
  m.def(
      "sun",
      [](const py::object& direction, double radius_deg, const py::object& sun, const py::object& sky) -> ProbePtr {
        return std::make_shared<probes::SunProbe>(to_vec3(direction, "direction"), probes::radians(radius_deg),
                                                  radiance_arg(sun, "sun"), radiance_arg(sky, "sky"));
      },
      py::arg("direction"), py::arg("radius_deg"), py::arg("sun"), py::arg("sky"),
      "A sun disk of angular radius radius_deg and radiance sun over a uniform "
      "sky.");
  m.def(
      "checker",
      [](const py::object& n_theta, const py::object& n_phi, const py::object& a, const py::object& b) -> ProbePtr {
        return std::make_shared<probes::CheckerProbe>(int_arg(n_theta, "n_theta", 1, kMaxCheckerCells),
                                                      int_arg(n_phi, "n_phi", 1, kMaxCheckerCells),
                                                      radiance_arg(a, "colour_a"), radiance_arg(b, "colour_b"));
      },
      py::arg("n_theta") = 8, py::arg("n_phi") = 16, py::arg("colour_a") = std::vector<double>{0.8, 0.8, 0.8},
      py::arg("colour_b") = std::vector<double>{0.1, 0.1, 0.1}, "n_theta x n_phi cells of two colours.");
  m.def(
      "outdoor",
      [](double elevation_deg, double azimuth_deg, double radius_deg, const py::object& sun_radiance,
         const py::object& seed, double cloud_cover) -> ProbePtr {
        probes::OutdoorSettings s;
        s.sun_elevation_deg = elevation_deg;
        s.sun_azimuth_deg = azimuth_deg;
        s.sun_radius_deg = radius_deg;
        if (!sun_radiance.is_none()) s.sun_radiance = radiance_arg(sun_radiance, "sun_radiance");
        if (!probes::valid_radiance(s.sun_radiance)) throw ArgumentError("sun_radiance: must be finite and >= 0");
        if (!(radius_deg > 0.0 && radius_deg <= 90.0)) throw ArgumentError("radius_deg: must be in (0, 90]");
        if (!(cloud_cover >= 0.0 && cloud_cover <= 1.0)) throw ArgumentError("cloud_cover: must be in [0, 1]");
        s.seed = static_cast<std::uint32_t>(integer_arg(seed, "seed", 0, 0xffffffffLL));
        s.cloud_cover = cloud_cover;
        return std::make_shared<probes::OutdoorProbe>(s);
      },
      py::arg("elevation_deg") = probes::OutdoorSettings{}.sun_elevation_deg,
      py::arg("azimuth_deg") = probes::OutdoorSettings{}.sun_azimuth_deg,
      py::arg("radius_deg") = probes::OutdoorSettings{}.sun_radius_deg, py::arg("sun_radiance") = py::none(),
      py::arg("seed") = probes::OutdoorSettings{}.seed, py::arg("cloud_cover") = probes::OutdoorSettings{}.cloud_cover,
      "envkit's procedural outdoor sky (the default probe with these "
      "settings).");
  m.def(
      "default", []() -> ProbePtr { return std::shared_ptr<Probe>(probes::make_default_probe()); },
      "The built-in default probe.");
}

}  // namespace envkit::python
