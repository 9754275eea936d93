// envkit.EnvMap: reading, writing, converting, rotating, resizing, per-texel
// geometry, statistics and comparison. Every method is the library call the
// command-line tool makes (envconvert, envinfo, envdiff), so results are the
// tools' results bit for bit.
#include <envkit/core/error.h>
#include <envkit/envmap/conversion.h>
#include <envkit/envmap/map_compare.h>
#include <envkit/envmap/map_stats.h>
#include <envkit/envmap/sun.h>
#include <envkit/io/image_io.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/maps/view_spec.h>
#include <envkit/resample/filter.h>
#include <pybind11/stl.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "args.h"
#include "arrays.h"
#include "bindings.h"
#include "envmap_object.h"
#include "rotation_arg.h"
#include "view_args.h"

namespace envkit::python {

namespace {

using Ptr = std::shared_ptr<PyEnvMap>;

/// envconvert's --ball-centre X,Y and --ball-radius R: a mirror-ball photograph whose ball is not the inscribed disk.
struct BallArgs {
  std::optional<std::pair<double, double>> centre;
  std::optional<double> radius;
};

LoadOptions load_options(const std::optional<std::string>& parameterization,
                         const std::optional<std::string>& convention, const std::optional<std::string>& layout,
                         const ViewArgs& view, const BallArgs& ball = {}) {
  LoadOptions o;
  argument_value([&] {
    if (parameterization) o.kind = parse_kind(*parameterization);
    if (layout) o.layout = parse_layout(*layout);
    if (convention) o.convention = &envkit::convention(*convention);
  });
  if (view.given()) {
    // As envconvert: view options describe an input only together with --from perspective|fisheye.
    if (!o.kind || !is_view_kind(*o.kind))
      throw ArgumentError("view: describes a camera view: add parameterization='perspective' or 'fisheye'");
    o.view = argument_value([&] { return view_params(view, *o.kind); });
  }
  if (ball.centre || ball.radius) {
    if (!o.kind || *o.kind != Kind::MirrorBall)
      throw ArgumentError(
          "ball_centre/ball_radius: describe a mirror-ball photograph: add parameterization='mirrorball'");
    if (ball.centre) {
      o.ball_cx = ball.centre->first;
      o.ball_cy = ball.centre->second;
    }
    if (ball.radius && !(*ball.radius > 0.0 && *ball.radius <= 1e7))
      throw ArgumentError("ball_radius: " + std::to_string(*ball.radius) + " is outside (0, 1e7]");
    o.ball_radius = ball.radius;
  }
  return o;
}

Ptr from_file(const std::string& path, const std::optional<std::string>& parameterization,
              const std::optional<std::string>& convention, const std::optional<std::string>& layout,
              const std::optional<std::string>& colorspace, const std::optional<std::string>& fix_nonfinite,
              const py::object& view, const std::optional<std::pair<double, double>>& ball_centre,
              const std::optional<double>& ball_radius) {
  LoadOptions o =
      load_options(parameterization, convention, layout, ViewArgs{view}, BallArgs{ball_centre, ball_radius});
  if (colorspace) o.read.colorspace = *colorspace;
  if (fix_nonfinite) o.read.nonfinite = argument_value([&] { return parse_nonfinite_policy(*fix_nonfinite); });
  auto p = std::make_shared<PyEnvMap>();
  Detection d;
  {
    py::gil_scoped_release release;
    p->map = file_operation([&] { return load_envmap(path, o, &d); });
  }
  if (d.kind == Kind::CubeMap) p->layout = d.layout;
  p->name = path;
  p->source = std::filesystem::path(path).filename().string();
  return p;
}

Ptr from_array(const py::object& array, const std::optional<std::string>& parameterization,
               const std::optional<std::string>& convention, const std::optional<std::string>& layout,
               const py::object& view, const std::optional<std::pair<double, double>>& ball_centre,
               const std::optional<double>& ball_radius) {
  auto p = std::make_shared<PyEnvMap>();
  Detection d;
  const LoadOptions o =
      load_options(parameterization, convention, layout, ViewArgs{view}, BallArgs{ball_centre, ball_radius});
  Image image = image_from_array(array, "array");
  try {
    p->map = make_envmap(std::move(image), p->name, o, &d);
  } catch (const Error& e) {
    // The array's shape fits no parameterization (or not the one given): a bad argument value.
    throw py::value_error(std::string("array: ") + e.what());
  }
  if (d.kind == Kind::CubeMap) p->layout = d.layout;
  return p;
}

py::array mat3_array(const Mat3& m) {
  py::array_t<double> out({3, 3});
  auto v = out.mutable_unchecked<2>();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) v(r, c) = m[r][c];
  return out;
}

/// envkit.ConversionError: arguments of a conversion that do not go together (a layout for a lat-long, a view for
/// a cube, a field of view out of the lens's range). Both an envkit.Error, as every refusal of the module was, and
/// a ValueError: a bad argument value.
py::handle g_conversion_error;

/// Names of the arguments that gave a request's fields, for its refusals.
struct ConvertArgNames {
  std::string size = "size";  ///< the argument that gave the size ("nside" for HEALPix, "rotation" for rotate())
  Kind to = Kind::LatLong;
};

[[noreturn]] void raise_conversion_error(const std::string& message) {
  PyErr_SetString(g_conversion_error.ptr(), message.c_str());
  throw py::error_already_set();
}

/// A refused request as the Python exception that names the arguments at fault. Needs the GIL.
[[noreturn]] void raise_refusal(const ConversionError& e, const ConvertArgNames& names) {
  switch (e.field) {
    case ConversionField::Size:  // a request too large is a ValueError, as every size argument's
      throw py::value_error(names.size + ": " + e.message);
    case ConversionField::Height:
      if (is_view_kind(names.to)) throw py::value_error("size: give either size=(width, height) or aspect, not both");
      throw py::value_error("size: (width, height) applies to camera views; give N for " + kind_name(names.to));
    case ConversionField::View:
    case ConversionField::Aspect:
      if (!is_view_kind(names.to))
        raise_conversion_error(
            "view_dir/roll/fov/fov_axis/lens/aspect describe a camera view: convert to perspective or fisheye");
      raise_conversion_error(e.message);  // the lens's range, as envconvert prints it after --fov/--lens
    default:
      raise_conversion_error(e.what());  // "layout: applies to cube maps only"
  }
}

/// The conversion `request` asks of `src`, as envconvert performs it (validate, output_spec, convert), onto `spec`
/// when given instead of output_spec's.
Ptr converted(const PyEnvMap& src, const ConversionRequest& request, const ConvertArgNames& names,
              const std::optional<ParamSpec>& spec = std::nullopt) {
  auto out = std::make_shared<PyEnvMap>();
  try {
    py::gil_scoped_release release;
    validate(request);
    out->map = spec ? convert(src.map, request, *spec) : convert(src.map, request);
  } catch (const ConversionError& e) {
    raise_refusal(e, names);
  }
  if (request.to == Kind::CubeMap)
    out->layout = request.layout.value_or(output_convention(request, src.map).cube_layout);
  out->filter = filter_name(request.filter);
  out->source = src.source;
  return out;
}

/// A request for a map like `p` (same kind, convention, layout and, for a camera view, the same view and aspect):
/// what rotate() and resize() resample onto.
ConversionRequest same_kind_request(const PyEnvMap& p, const std::string& filter) {
  ConversionRequest r;
  r.to = p.map.param->kind();
  r.convention = &envkit::convention(p.map.convention);
  if (r.to == Kind::CubeMap) r.layout = p.layout;
  if (is_view_kind(r.to)) {
    r.view = *p.map.param->view();
    r.aspect = double(p.map.param->width()) / p.map.param->height();
  }
  r.filter = argument_value([&] { return parse_filter(filter); });
  return r;
}

/// EnvMap.convert: envconvert's options, with size=(w, h) as well as --size N --aspect A for camera views and
/// nside= for HEALPix (--size N_side). Names are parsed here; the request's combinations are validate()'s.
Ptr convert_map(const PyEnvMap& p, const std::string& to, const py::object& size_arg, const std::string& filter,
                const std::optional<std::string>& convention, const py::object& rotate,
                const std::optional<std::string>& layout, const ViewArgs& view_args, const py::object& aspect_obj,
                const py::object& nside_obj) {
  ConversionRequest r;
  r.aspect = optional_real_arg(aspect_obj, "aspect", 1e-3, 1e3);
  const std::optional<int> nside = optional_int_arg(nside_obj, "nside", 1, int(kMaxSizeArg));
  argument_value([&] {
    r.to = parse_kind(to);
    r.convention = &envkit::convention(convention ? *convention : p.map.convention);
    if (layout) r.layout = parse_layout(*layout);
  });
  int size = 0;
  std::optional<ParamSpec> latlong_spec;
  if (py::isinstance<py::tuple>(size_arg) || py::isinstance<py::list>(size_arg)) {
    const auto wh = int_pair_arg(size_arg, "size", 1, int(kMaxSizeArg));
    size = wh.first;
    r.height = wh.second;
    if (r.to == Kind::LatLong) {
      // A lat-long of any aspect (py360convert's c2e h, w): the spec at natural size h, w columns wide.
      latlong_spec = spec_for(Kind::LatLong, wh.second, *r.convention);
      latlong_spec->width = wh.first;
      check_size_arg("size", "latlong map", wh.first, wh.second, 32.0);
      size = wh.second;
      r.height.reset();
    }
  } else {
    size = int_arg(size_arg, "size", 0, int(kMaxSizeArg));  // 0: about the input's texel density
  }
  if (nside) {
    if (r.to != Kind::HEALPix) throw py::value_error("nside: applies to healpix only");
    if (size > 0) throw py::value_error("nside: give either size or nside, not both");
    size = *nside;
  }
  if (size > 0) r.size = size;
  argument_value([&] {
    r.view = parsed_view(view_args, r.to);
    r.filter = parse_filter(filter);
    if (!rotate.is_none()) r.rotation = rotation_arg(rotate);
  });
  return converted(p, r, ConvertArgNames{nside ? "nside" : "size", r.to}, latlong_spec);
}

/// A map of zeros laid out like envconvert's output of `kind` at natural size N: allocated by envkit, so that
/// filling .data in place is the way to build a large map without an input copy.
Ptr blank(const py::object& size_arg, const std::string& parameterization, const py::object& channels_arg,
          const std::optional<std::string>& convention, const std::optional<std::string>& layout,
          const py::object& view) {
  const int size = int_arg(size_arg, "size", 1, int(kMaxSizeArg));
  const int channels = int_arg(channels_arg, "channels", 1, 4);
  const Kind kind = argument_value([&] { return parse_kind(parameterization); });
  const Convention& conv =
      argument_value([&]() -> const Convention& { return envkit::convention(convention.value_or("envkit")); });
  std::optional<CubeLayout> l;
  if (layout) l = argument_value([&] { return parse_layout(*layout); });
  const std::optional<ViewParams> v = argument_value([&] { return view_params(ViewArgs{view}, kind); });
  if (v && !is_view_kind(kind))
    throw ArgumentError("view: describes a camera view: add parameterization='perspective' or 'fisheye'");
  const ParamSpec spec = is_view_kind(kind) ? view_spec(kind, size, 1.0, v.value_or([&] {
    ViewParams d;
    d.fov_degrees = default_fov_degrees(kind);
    return d;
  }()),
                                                        conv)
                                            : spec_for(kind, size, conv, l);
  check_size_arg("size", kind_name(kind) + " map", spec.width, spec.height, double(channels) * sizeof(float));
  auto p = std::make_shared<PyEnvMap>();
  p->map.param = make_parameterization(spec);
  p->map.convention = conv.name;
  {
    py::gil_scoped_release release;
    p->map.image = Image(p->map.param->width(), p->map.param->height(), channels);
  }
  if (kind == Kind::CubeMap) p->layout = l.value_or(conv.cube_layout);
  return p;
}

// detect_sun as a dict (the keys of envinfo --json's "sun"), or None.
py::object sun_dict(const PyEnvMap& p) {
  std::optional<SunEstimate> sun;
  {
    py::gil_scoped_release release;
    sun = detect_sun(p.map);
  }
  if (!sun) return py::none();
  py::dict d;
  d["direction"] = std::array<double, 3>{sun->direction.x, sun->direction.y, sun->direction.z};
  d["angular_radius_deg"] = sun->angular_radius * 180.0 / kPi;
  d["solid_angle"] = sun->solid_angle;
  d["texels"] = sun->texels;
  d["radiance"] = sun->radiance;
  d["power"] = sun->power;
  d["power_share"] = sun->power_share;
  d["clipped"] = sun->clipped;
  d["clipped_texels"] = sun->clipped_texels;
  return d;
}

py::dict stats_dict(const PyEnvMap& p) {
  MapStats s;
  {
    py::gil_scoped_release release;
    s = map_statistics(p.map);
  }
  py::list channels;
  for (std::size_t c = 0; c < s.channels.size(); ++c) {
    const ChannelStats& ch = s.channels[c];
    py::dict d;
    d["channel"] = ch.name;
    d["alpha"] = int(c) == p.map.image.alpha_channel;
    d["power"] = ch.power;
    d["mean_radiance"] = ch.mean_radiance;
    d["min"] = ch.min;
    d["max"] = ch.max;
    d["texel_mean"] = ch.texel_mean;
    channels.append(d);
  }
  py::dict out;
  out["width"] = p.map.image.width;
  out["height"] = p.map.image.height;
  out["channels"] = p.map.image.channel_names;
  out["parameterization"] = kind_name(p.map.param->kind());
  out["description"] = p.map.param->describe();
  out["convention"] = p.map.convention;
  out["solid_angle"] = s.solid_angle;
  out["statistics"] = channels;
  return out;
}

py::dict diff_dict(const PyEnvMap& a, const PyEnvMap& b, const std::string& filter, const std::string& metric) {
  const Filter f = argument_value([&] { return parse_filter(filter); });
  if (metric != "relmse" && metric != "rmse" && metric != "max" && metric != "power")
    throw ArgumentError("metric: '" + metric + "' is not relmse, rmse, max or power");
  MapComparison c;
  {
    py::gil_scoped_release release;
    c = compare_maps(a.map, b.map, f, a.name, b.name);
  }
  py::list power;
  for (std::size_t k = 0; k < c.channels.size(); ++k) {
    py::dict d;
    d["channel"] = c.channels[k];
    d["a"] = c.power_a[k];
    d["b"] = c.power_b[k];
    d["relative_difference"] = c.power_rel[k];
    power.append(d);
  }
  py::dict max;
  max["value"] = c.max.value;
  if (c.max.i >= 0) {
    max["texel"] = py::make_tuple(c.max.i, c.max.j);
    max["channel"] = c.channels[c.max.channel];
    max["direction"] = from_vec3(c.max.direction);
  }
  py::dict out;
  out["filter"] = filter_name(f);
  out["compared_solid_angle"] = c.compared_solid_angle;
  out["rmse"] = c.rmse;
  out["relmse"] = c.relmse;
  out["max_abs_error"] = max;
  out["power"] = power;
  out["power_max_relative_difference"] = c.power_max_rel;
  out["metric"] = metric;
  out["value"] = comparison_metric(c, metric);
  return out;
}

py::array solid_angles(const PyEnvMap& p) {
  const int w = p.map.param->width(), h = p.map.param->height();
  py::array_t<double> out({h, w});
  double* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    const SolidAngleTable omega(*p.map.param);
    for (int j = 0; j < h; ++j)
      for (int i = 0; i < w; ++i) o[std::size_t(j) * w + i] = omega(i, j);
  }
  return out;
}

py::array directions(const PyEnvMap& p) {
  const int w = p.map.param->width(), h = p.map.param->height();
  py::array_t<double> out({h, w, 3});
  double* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    const TexelDirections dirs(*p.map.param);
    const Mat3 to_world = p.map.to_world();
    parallel_chunks(std::size_t(h), [&](std::size_t j0, std::size_t j1) {
      for (std::size_t j = j0; j < j1; ++j)
        for (int i = 0; i < w; ++i) {
          Vec3 d(0, 0, 0);
          double* t = o + (j * w + i) * 3;
          if (dirs.centre(i, int(j), d))
            d = apply(to_world, d);
          else
            d = Vec3(0, 0, 0);
          t[0] = d.x, t[1] = d.y, t[2] = d.z;
        }
    });
  }
  return out;
}

bool usable_direction(const double* d) {
  const double n = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  return std::isfinite(n) && n > 0.0;
}

py::array texel_of(const PyEnvMap& p, const py::object& input) {
  std::size_t n = 0;
  const DoubleArray in = vectors(input, 3, "directions", n);
  py::array_t<double> out(result_shape(in, 2));
  const double* d = in.data();
  double* o = out.mutable_data();
  std::size_t bad = 0;
  {
    py::gil_scoped_release release;
    const Mat3 to_map = transposed(p.map.to_world());  // frames and rotations are orthonormal
    for (std::size_t k = 0; k < n; ++k) {
      if (!usable_direction(d + 3 * k)) {
        ++bad;
        o[2 * k] = o[2 * k + 1] = 0.0;
        continue;
      }
      const Vec2 pos = p.map.param->to_image(apply(to_map, Vec3(d[3 * k], d[3 * k + 1], d[3 * k + 2])));
      o[2 * k] = pos.x;
      o[2 * k + 1] = pos.y;
    }
  }
  if (bad > 0) throw py::value_error("directions: " + std::to_string(bad) + " zero or non-finite directions");
  return out;
}

py::array lookup(const PyEnvMap& p, const py::object& input, const std::string& filter) {
  const Filter f = argument_value([&] { return parse_filter(filter); });
  if (f == Filter::Area)
    throw ArgumentError(
        "lookup: the area filter integrates over texels; use nearest, "
        "bilinear or bicubic");
  std::size_t n = 0;
  const DoubleArray in = vectors(input, 3, "directions", n);
  const int c = p.map.image.channels;
  py::array_t<float> out(result_shape(in, c));
  const double* d = in.data();
  float* o = out.mutable_data();
  std::atomic<std::size_t> bad{0};
  {
    py::gil_scoped_release release;
    const Mat3 to_map = transposed(p.map.to_world());
    const TexelSource source(p.map.image, *p.map.param);
    parallel_chunks(n, [&](std::size_t k0, std::size_t k1) {
      for (std::size_t k = k0; k < k1; ++k) {
        if (!usable_direction(d + 3 * k)) {
          ++bad;
          std::fill(o + k * c, o + (k + 1) * c, 0.0f);
          continue;
        }
        const Vec2 pos = p.map.param->to_image(apply(to_map, Vec3(d[3 * k], d[3 * k + 1], d[3 * k + 2])));
        source.sample(pos, f, o + k * c);
      }
    });
  }
  if (bad > 0) throw py::value_error("directions: " + std::to_string(bad.load()) + " zero or non-finite directions");
  return out;
}

void write(const PyEnvMap& p, const std::string& path, bool half, const std::string& compression) {
  SaveOptions so;
  so.write.pixel_type = half ? PixelType::Half : PixelType::Auto;
  so.write.compression = compression;
  so.filter = p.filter;
  so.source = p.source;
  ClampReport clamped;
  {
    py::gil_scoped_release release;
    clamped = file_operation([&] { return save_envmap(path, p.map, so); });
  }
  warn_clamped(clamped, path);
}

}  // namespace

void bind_envmap(py::module_& m) {
  const py::tuple bases = py::make_tuple(m.attr("ArgumentError"));
  g_conversion_error = PyErr_NewException("_envkit.ConversionError", bases.ptr(), nullptr);  // lives with the module
  if (!g_conversion_error) throw py::error_already_set();
  m.attr("ConversionError") = g_conversion_error;
  py::class_<PyEnvMap, Ptr>(m, "EnvMap",
                            R"(An environment map: float32 pixels (H x W x C, linear, row 0 at the top),
a parameterization and a convention (docs/PYTHON.md).

EnvMap(path, parameterization=None, convention=None, layout=None, colorspace=None, fix_nonfinite=None)
    reads a file (any format envkit reads; a '%' in the path reads six cube faces). Without
    `parameterization` it is detected as envconvert does (metadata, then the aspect ratio).
EnvMap(array, parameterization=None, convention=None, layout=None, view=None)
    wraps an H x W x C (or H x W) array of 1 to 4 channels (copied once into envkit's storage: see
    docs/PYTHON.md for why it cannot be wrapped).
view: for parameterization 'perspective' or 'fisheye', the camera view (a dict as EnvMap.view returns, with
keys view_dir, roll, fov, fov_axis, lens; default: the file's envkit:view metadata) - envconvert --from
perspective|fisheye --view-dir ... .
ball_centre=(x, y), ball_radius=r: a mirror-ball photograph (parameterization 'mirrorball') whose ball is not the
inscribed disk, in pixels - envconvert --ball-centre X,Y --ball-radius R.

Parameterizations and conventions are names, as on the command line: latlong, cube, mirrorball, angular,
octahedral, paraboloid, ...; envkit, openexr, hdrshop, angmap-cal, blender, gl.)")
      .def(py::init(&from_file), py::arg("path"), py::arg("parameterization") = py::none(),
           py::arg("convention") = py::none(), py::arg("layout") = py::none(), py::arg("colorspace") = py::none(),
           py::arg("fix_nonfinite") = py::none(), py::arg("view") = py::none(), py::arg("ball_centre") = py::none(),
           py::arg("ball_radius") = py::none())
      .def(py::init(&from_array), py::arg("array"), py::arg("parameterization") = py::none(),
           py::arg("convention") = py::none(), py::arg("layout") = py::none(), py::arg("view") = py::none(),
           py::arg("ball_centre") = py::none(), py::arg("ball_radius") = py::none())
      .def_static("read", &from_file, py::arg("path"), py::arg("parameterization") = py::none(),
                  py::arg("convention") = py::none(), py::arg("layout") = py::none(),
                  py::arg("colorspace") = py::none(), py::arg("fix_nonfinite") = py::none(),
                  py::arg("view") = py::none(), py::arg("ball_centre") = py::none(),
                  py::arg("ball_radius") = py::none(), "Reads a map from a file (same as the constructor).")
      .def_static("blank", &blank, py::arg("size"), py::arg("parameterization") = "latlong", py::arg("channels") = 3,
                  py::arg("convention") = py::none(), py::arg("layout") = py::none(), py::arg("view") = py::none(),
                  R"(A map of zeros at natural size N (lat-long 2N x N, cube faces N x N, views N x N, HEALPix
4N x 3N), in envkit's own storage: fill .data in place to build a map without copying an input array.)")
      .def_static("from_array", &from_array, py::arg("array"), py::arg("parameterization") = py::none(),
                  py::arg("convention") = py::none(), py::arg("layout") = py::none(), py::arg("view") = py::none(),
                  py::arg("ball_centre") = py::none(), py::arg("ball_radius") = py::none(),
                  "A map around an array (same as the constructor).")
      .def("write", &write, py::arg("path"), py::arg("half") = false, py::arg("compression") = "",
           R"(Writes the map (format from the extension; a '%' writes six cube faces), atomically, with the
metadata envconvert writes. half: half floats (OpenEXR; values beyond 65504, a sun, are clamped with a
UserWarning); compression: none, zip, piz, dwaa, ...)")
      .def_property_readonly(
          "data", [](py::object self) { return image_view(self.cast<PyEnvMap&>().map.image, self); },
          "The pixels as an H x W x C float32 array sharing the map's memory "
          "(no copy; writes go to the map).")
      .def_property_readonly("width", [](const PyEnvMap& p) { return p.map.image.width; })
      .def_property_readonly("height", [](const PyEnvMap& p) { return p.map.image.height; })
      .def_property_readonly(
          "channels", [](const PyEnvMap& p) { return p.map.image.channel_names; },
          "Channel names, e.g. ['R', 'G', 'B'].")
      .def_property_readonly("alpha_channel", [](const PyEnvMap& p) { return p.map.image.alpha_channel; })
      .def_property_readonly("parameterization", [](const PyEnvMap& p) { return kind_name(p.map.param->kind()); })
      .def_property_readonly("layout",
                             [](const PyEnvMap& p) -> py::object {
                               if (!p.layout) return py::none();
                               return py::str(layout_name(*p.layout));
                             })
      .def_property_readonly("convention", [](const PyEnvMap& p) { return p.map.convention; })
      .def_property_readonly(
          "view",
          [](const PyEnvMap& p) -> py::object {
            const ViewParams* v = p.map.param->view();
            if (!v) return py::none();
            return view_dict(*v);
          },
          "Camera views: dict(view_dir, roll, fov, fov_axis, lens), to pass back as view=; None for maps.")
      .def_property_readonly("metadata", [](const PyEnvMap& p) { return p.map.image.metadata; })
      .def_property_readonly(
          "to_world", [](const PyEnvMap& p) { return mat3_array(p.map.to_world()); },
          "3x3 matrix taking map-frame directions to the envkit world (+Y up).")
      .def("describe", [](const PyEnvMap& p) { return p.map.param->describe(); })
      .def("__repr__",
           [](const PyEnvMap& p) {
             return "<envkit.EnvMap " + p.map.param->describe() + ", " + std::to_string(p.map.image.channels) +
                    " channels, convention " + p.map.convention + ">";
           })
      .def(
          "convert",
          [](const PyEnvMap& p, const std::string& to, const py::object& size, const std::string& filter,
             const std::optional<std::string>& convention, const py::object& rotate,
             const std::optional<std::string>& layout, const py::object& view, const py::object& view_dir,
             const py::object& roll, const py::object& fov, const py::object& fov_axis, const py::object& lens,
             const py::object& aspect, const py::object& nside) {
            return convert_map(p, to, size, filter, convention, rotate, layout,
                               ViewArgs{view, view_dir, roll, fov, fov_axis, lens}, aspect, nside);
          },
          py::arg("to"), py::arg("size") = 0, py::arg("filter") = "area", py::arg("convention") = py::none(),
          py::arg("rotate") = py::none(), py::arg("layout") = py::none(), py::kw_only(), py::arg("view") = py::none(),
          py::arg("view_dir") = py::none(), py::arg("roll") = py::none(), py::arg("fov") = py::none(),
          py::arg("fov_axis") = py::none(), py::arg("lens") = py::none(), py::arg("aspect") = py::none(),
          py::arg("nside") = py::none(),
          R"(Resamples to another parameterization: envconvert IN -o OUT --to TO [--size N] [--filter F]
[--convention C] [--rotate R] [--layout L] [--view-dir D --roll DEG --fov DEG --fov-axis h|v --lens L
--aspect A]. size 0 keeps about the input's texel density; convention defaults to this map's; rotate:
'yaw,pitch,roll', 3 angles in degrees or a 3x3 matrix (what is seen in direction d is then seen in R d). The
area filter conserves power.

Camera views (to='perspective' or 'fisheye'): size N is the width, the height N / aspect (or size=(w, h));
view_dir (x, y, z) or (yaw, pitch) in degrees (yaw about +Y from +Z towards +X), roll, fov (perspective: across
the width, or the height with fov_axis='v'; (h, v): both, pixels need not be square; fisheye: across the image
circle, default 180), lens (equidistant, equisolid, orthographic, stereographic; on a perspective view
'orthographic' makes the planar orthographic projection); or view= a dict as EnvMap.view returns. A lat-long takes
size=(w, h) of any aspect. Directions the view does not
see come out with alpha 0. HEALPix: nside=N (image 4N x 3N), or size=N.)")
      .def(
          "rotate",
          [](const PyEnvMap& p, const py::object& rotation, const std::string& filter) {
            ConversionRequest r = same_kind_request(p, filter);
            if (!rotation.is_none()) r.rotation = rotation_arg(rotation);
            return converted(p, r, ConvertArgNames{"rotation", r.to});
          },
          py::arg("rotation"), py::arg("filter") = "area",
          "The environment rotated by R, on a map of the same parameterization "
          "and convention (size from the "
          "texel density, as convert).")
      .def(
          "resize",
          [](const PyEnvMap& p, const py::object& size, const std::string& filter) {
            const int n = int_arg(size, "size", 1, int(kMaxSizeArg));
            ConversionRequest r = same_kind_request(p, filter);
            r.size = n;
            return converted(p, r, ConvertArgNames{"size", r.to});
          },
          py::arg("size"), py::arg("filter") = "area",
          "Same parameterization at natural size N (lat-long 2N x N, cube "
          "faces N x N). The default area filter "
          "conserves power per channel (energy-conserving resize).")
      .def("solid_angles", &solid_angles,
           "Exact solid angle of every texel (H x W float64, steradians; 0 "
           "without data).")
      .def("directions", &directions,
           "World direction (+Y up) of every texel centre, H x W x 3 float64 "
           "(zeros where there is no data).")
      .def("texel_of", &texel_of, py::arg("directions"),
           "Continuous image positions (x, y) seeing world directions of shape "
           "(..., 3): shape (..., 2). "
           "Texel (i, j) covers [i, i+1) x [j, j+1).")
      .def("lookup", &lookup, py::arg("directions"), py::arg("filter") = "bilinear",
           "Radiance seen in world directions (..., 3) -> (..., C) float32 "
           "(nearest, bilinear or bicubic).")
      .def("info", &stats_dict,
           "What envinfo prints: power, mean radiance, min, max, texel mean "
           "per channel.")
      .def("sun", &sun_dict,
           "The sun envinfo reports (libenv detect_sun): a dict with direction (world, +Y up), "
           "angular_radius_deg, solid_angle, texels, radiance, power, power_share, clipped, clipped_texels; "
           "None when the map has no sun.")
      .def(
          "power", [](const PyEnvMap& p) { return total_power(p.map.image, *p.map.param); },
          "Total power per channel: sum of L x texel solid angle (double).")
      .def("diff", &diff_dict, py::arg("other"), py::arg("filter") = "area", py::arg("metric") = "relmse",
           "What envdiff self other prints: other resampled onto this map; "
           "rmse, relmse, max error, power.")
      .def(
          "copy",
          [](const PyEnvMap& p) {
            auto out = std::make_shared<PyEnvMap>(
                PyEnvMap{EnvMap{p.map.image, p.map.param->clone(), p.map.convention, p.map.rotation}, p.layout,
                         p.filter, p.source, p.name});
            return out;
          },
          "A deep copy.");

  m.def("conventions", &convention_names, "Names of the orientation conventions.");
  m.def(
      "read_image",
      [](const std::string& path) {
        Image image;
        {
          py::gil_scoped_release release;
          image = file_operation([&] { return read_image(path); });
        }
        return image_array(std::move(image));
      },
      py::arg("path"),
      "Reads any image envkit reads as an H x W x C float32 array (linear "
      "working space).");
}

}  // namespace envkit::python
