// EnvMap methods a skylibs user reaches for (docs/PYTHON.md, "Parity"): image coordinates of texel centres,
// background colour, intensity, hemisphere masks and values, mean light vectors, the von Mises-Fisher blur, and
// maps from OCamCalib fisheye photographs. Each works on the map's texel geometry as libenv gives it (texel centre
// directions, exact solid angles), in the envkit world frame (+Y up).
#include <envkit/core/error.h>
#include <envkit/io/color.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/perspective.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/maps/view_spec.h>
#include <envkit/resample/filter.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "args.h"
#include "arrays.h"
#include "bindings.h"
#include "envmap_object.h"
#include "view_args.h"

namespace envkit::python {

namespace {

using Ptr = std::shared_ptr<PyEnvMap>;

/// World direction (envkit frame) and exact solid angle of every texel whose centre holds data.
struct WorldTexels {
  int width = 0, height = 0;
  std::vector<Vec3> dir;                ///< zero where the centre holds no data
  std::vector<double> omega;            ///< steradians
  std::vector<unsigned char> has_data;  ///< the centre sees a direction
  double total_omega = 0.0;             ///< sum of omega over texels with data (4 pi for a full map)
};

WorldTexels world_texels(const EnvMap& m) {
  WorldTexels t;
  t.width = m.param->width();
  t.height = m.param->height();
  const std::size_t n = std::size_t(t.width) * t.height;
  t.dir.assign(n, Vec3(0, 0, 0));
  t.omega.assign(n, 0.0);
  t.has_data.assign(n, 0);
  const TexelDirections dirs(*m.param);
  const SolidAngleTable omega(*m.param);
  const Mat3 to_world = m.to_world();
  for (int j = 0; j < t.height; ++j)
    for (int i = 0; i < t.width; ++i) {
      const std::size_t k = std::size_t(j) * t.width + i;
      Vec3 d;
      if (!dirs.centre(i, j, d)) continue;
      t.dir[k] = apply(to_world, d);
      t.omega[k] = omega(i, j);
      t.has_data[k] = 1;
      t.total_omega += t.omega[k];
    }
  return t;
}

/// A unit normal from 3 finite numbers (ValueError for a zero vector).
Vec3 unit_normal(const py::handle& value, const std::string& name) {
  const Vec3 n = to_vec3(value, name);
  const double len = n.length();
  if (!(len > 0.0)) throw py::value_error(name + ": a zero vector has no direction");
  return n / len;
}

/// Channel values to write from `value` (a number, one per colour channel, or one per channel); `set[c]` says
/// which channels it sets (a number or colour values leave alpha alone).
struct ChannelValues {
  std::vector<float> value;
  std::vector<bool> set;
};

ChannelValues channel_values(const Image& image, const py::handle& value, const std::string& name) {
  const py::array a = real_array(value, name);
  const auto v = a.cast<py::array_t<double, py::array::c_style | py::array::forcecast>>();
  const std::size_t count = std::size_t(v.size());
  const int c = image.channels, colour = image.color_channels();
  if (count != 1 && count != std::size_t(colour) && count != std::size_t(c))
    throw py::value_error(name + ": expected 1, " + std::to_string(colour) +
                          (colour != c ? " (colour) or " + std::to_string(c) : std::string()) + " values, got " +
                          std::to_string(count));
  ChannelValues out{std::vector<float>(std::size_t(c), 0.0f), std::vector<bool>(std::size_t(c), false)};
  const double* d = v.data();
  for (std::size_t k = 0; k < count; ++k)
    if (!std::isfinite(d[k])) throw py::value_error(name + ": values must be finite");
  int next = 0;
  for (int ch = 0; ch < c; ++ch) {
    if (count != std::size_t(c) && ch == image.alpha_channel) continue;
    out.value[std::size_t(ch)] = float(count == 1 ? d[0] : d[next++]);
    out.set[std::size_t(ch)] = true;
  }
  return out;
}

/// A map on `p`'s grid, convention and orientation holding `image`.
Ptr same_grid_map(const PyEnvMap& p, Image&& image) {
  return std::make_shared<PyEnvMap>(
      PyEnvMap{EnvMap{std::move(image), p.map.param->clone(), p.map.convention, p.map.rotation}, p.layout, p.filter,
               p.source, p.name});
}

void fill_texel(float* px, const ChannelValues& v) {
  for (std::size_t ch = 0; ch < v.value.size(); ++ch)
    if (v.set[ch]) px[ch] = v.value[ch];
}

py::tuple image_coordinates(const PyEnvMap& p) {
  const int w = p.map.image.width, h = p.map.image.height;
  py::array_t<double> u({h, w}), v({h, w});
  double* pu = u.mutable_data();
  double* pv = v.mutable_data();
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      pu[std::size_t(j) * w + i] = (i + 0.5) / w;
      pv[std::size_t(j) * w + i] = (j + 0.5) / h;
    }
  return py::make_tuple(u, v);
}

/// Texels outside the map's coverage: the centre holds no data, or the coverage alpha is 0.
py::object set_background(py::object self, const py::object& color) {
  PyEnvMap& p = self.cast<PyEnvMap&>();
  Image& img = p.map.image;
  const ChannelValues v = channel_values(img, color, "color");
  const TexelDirections dirs(*p.map.param);
  for (int j = 0; j < img.height; ++j)
    for (int i = 0; i < img.width; ++i) {
      float* px = img.at(i, j);
      Vec3 d;
      const bool outside = !dirs.centre(i, j, d) || (img.alpha_channel >= 0 && px[img.alpha_channel] == 0.0f);
      if (outside) fill_texel(px, v);
    }
  return self;
}

/// Weights of the colour channels for an intensity `mode`: BT.709 luminance (the working space's, libenv's
/// luminance_weights), BT.601 luma weights, or the plain mean.
std::vector<double> intensity_weights(const Image& img, const std::string& mode) {
  const int colour = img.color_channels();
  std::string m = mode;
  std::transform(m.begin(), m.end(), m.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
  std::erase_if(m, [](char ch) { return ch == ' ' || ch == '.' || ch == '-' || ch == '_'; });
  if (m == "mean" || colour == 1) return std::vector<double>(std::size_t(colour), 1.0 / colour);
  const bool bt709 = m == "bt709" || m == "itubt709" || m == "rec709";
  const bool bt601 = m == "bt601" || m == "itubt601" || m == "rec601";
  if (!bt709 && !bt601) throw py::value_error("mode: '" + mode + "' is not bt709, bt601 or mean");
  if (colour != 3)
    throw py::value_error("mode: " + mode + " weighs R, G, B; this map has " + std::to_string(colour) +
                          " colour channels (use mode='mean')");
  if (bt601) return {0.299, 0.587, 0.114};
  const Vec3 y = luminance_weights();
  return {y.x, y.y, y.z};
}

/// Intensity of one texel: the weighted sum of its colour channels.
double texel_intensity(const Image& img, const float* px, const std::vector<double>& weights) {
  double s = 0.0;
  int k = 0;
  for (int ch = 0; ch < img.channels; ++ch)
    if (ch != img.alpha_channel) s += weights[std::size_t(k++)] * px[ch];
  return s;
}

Ptr intensity(const PyEnvMap& p, const std::string& mode) {
  const Image& src = p.map.image;
  const std::vector<double> weights = intensity_weights(src, mode);
  const bool alpha = src.alpha_channel >= 0;
  Image out(src.width, src.height, alpha ? 2 : 1);
  out.channel_names = alpha ? std::vector<std::string>{"Y", "A"} : std::vector<std::string>{"Y"};
  out.alpha_channel = alpha ? 1 : -1;
  out.metadata = src.metadata;
  for (int j = 0; j < src.height; ++j)
    for (int i = 0; i < src.width; ++i) {
      const float* px = src.at(i, j);
      float* o = out.at(i, j);
      o[0] = float(texel_intensity(src, px, weights));
      if (alpha) o[1] = px[src.alpha_channel];
    }
  return same_grid_map(p, std::move(out));
}

py::array hemisphere(const PyEnvMap& p, const py::object& normal) {
  const Vec3 n = unit_normal(normal, "normal");
  const WorldTexels t = world_texels(p.map);
  py::array_t<bool> out({t.height, t.width});
  bool* o = out.mutable_data();
  for (std::size_t k = 0; k < t.dir.size(); ++k) o[k] = t.has_data[k] && (t.dir[k] ^ n) > 0.0;
  return out;
}

py::object set_hemisphere(py::object self, const py::object& normal, const py::object& value) {
  PyEnvMap& p = self.cast<PyEnvMap&>();
  const Vec3 n = unit_normal(normal, "normal");
  const ChannelValues v = channel_values(p.map.image, value, "value");
  const WorldTexels t = world_texels(p.map);
  for (std::size_t k = 0; k < t.dir.size(); ++k)
    if (t.has_data[k] && (t.dir[k] ^ n) > 0.0) fill_texel(p.map.image.pixels.data() + k * p.map.image.channels, v);
  return self;
}

/// skylibs' mean light vector for normal n: (1 / Omega) sum over texels with d . n > 0 of Y(d) d Omega(d), with Y
/// the intensity and Omega the map's total solid angle (4 pi for a map of the whole sphere). Its component along n
/// is the cosine-weighted integral of Y over the hemisphere (the irradiance of Y) divided by Omega.
py::array mean_light_vectors(const PyEnvMap& p, const py::object& normals, const std::string& mode) {
  std::size_t n = 0;
  const DoubleArray in = vectors(normals, 3, "normals", n);
  const std::vector<double> weights = intensity_weights(p.map.image, mode);
  py::array_t<double> out(result_shape(in, 3));
  const double* nd = in.data();
  double* o = out.mutable_data();
  for (std::size_t k = 0; k < n; ++k) {
    const double len = std::sqrt(nd[3 * k] * nd[3 * k] + nd[3 * k + 1] * nd[3 * k + 1] + nd[3 * k + 2] * nd[3 * k + 2]);
    if (!(len > 0.0) || !std::isfinite(len)) throw py::value_error("normals: zero or non-finite normals");
  }
  {
    py::gil_scoped_release release;
    const WorldTexels t = world_texels(p.map);
    std::vector<double> y(t.dir.size(), 0.0);
    for (std::size_t k = 0; k < y.size(); ++k)
      if (t.has_data[k])
        y[k] = texel_intensity(p.map.image, p.map.image.pixels.data() + k * p.map.image.channels, weights) * t.omega[k];
    const double norm = t.total_omega > 0.0 ? 1.0 / t.total_omega : 0.0;
    parallel_chunks(n, [&](std::size_t k0, std::size_t k1) {
      for (std::size_t k = k0; k < k1; ++k) {
        const Vec3 nk(nd[3 * k], nd[3 * k + 1], nd[3 * k + 2]);
        double sx = 0, sy = 0, sz = 0;
        for (std::size_t i = 0; i < y.size(); ++i) {
          if (!t.has_data[i] || (t.dir[i] ^ nk) <= 0.0) continue;
          sx += y[i] * t.dir[i].x;
          sy += y[i] * t.dir[i].y;
          sz += y[i] * t.dir[i].z;
        }
        o[3 * k] = sx * norm, o[3 * k + 1] = sy * norm, o[3 * k + 2] = sz * norm;
      }
    });
  }
  return out;
}

/// Beyond this kappa (1 - cos), the von Mises-Fisher weight exp(kappa (cos - 1)) is below 1e-26 of its peak.
constexpr double kVmfCutoff = 60.0;

/// The map convolved with the von Mises-Fisher lobe C(kappa) exp(kappa mu . x): every texel with data becomes the
/// solid-angle weighted mean of all texels, weighted by the lobe around its centre direction (direct sum over texel
/// pairs, normalised by the sum of the weights, so that the discrete lobe keeps its unit integral at any texel size).
Ptr blur(const PyEnvMap& p, const py::object& kappa_arg) {
  const double kappa = real_arg(kappa_arg, "kappa", 0.0, 1e9);
  const Image& src = p.map.image;
  const int c = src.channels;
  Image out(src.width, src.height, c);
  out.channel_names = src.channel_names;
  out.alpha_channel = src.alpha_channel;
  out.metadata = src.metadata;
  {
    py::gil_scoped_release release;
    const WorldTexels t = world_texels(p.map);
    std::vector<std::size_t> texels;
    for (std::size_t k = 0; k < t.dir.size(); ++k)
      if (t.has_data[k] && t.omega[k] > 0.0) texels.push_back(k);
    parallel_chunks(t.dir.size(), [&](std::size_t k0, std::size_t k1) {
      std::vector<double> acc(static_cast<std::size_t>(c));
      for (std::size_t k = k0; k < k1; ++k) {
        if (!t.has_data[k]) continue;
        std::fill(acc.begin(), acc.end(), 0.0);
        double wsum = 0.0;
        for (const std::size_t s : texels) {
          const double e = kappa * (1.0 - (t.dir[k] ^ t.dir[s]));
          if (e > kVmfCutoff) continue;
          const double w = std::exp(-e) * t.omega[s];
          const float* px = src.pixels.data() + s * c;
          for (int ch = 0; ch < c; ++ch) acc[std::size_t(ch)] += w * px[ch];
          wsum += w;
        }
        float* o = out.pixels.data() + k * c;
        for (int ch = 0; ch < c; ++ch) o[ch] = wsum > 0.0 ? float(acc[std::size_t(ch)] / wsum) : 0.0f;
      }
    });
  }
  return same_grid_map(p, std::move(out));
}

/// Scaramuzza's omnidirectional camera model as OCamCalib calibrates it (calib_results.txt): pol (cam2world, in
/// ascending powers), invpol (world2cam, ascending), the centre (xc, yc) as (row, column), and the affine matrix
/// [c d; e 1]. Camera frame: x along image rows (down), y along columns (right), the optical axis along -z.
struct OcamModel {
  std::vector<double> invpol;
  double xc = 0, yc = 0, c = 1, d = 0, e = 0;
};

double calibration_number(const py::dict& calib, const char* key, std::optional<double> fallback = {}) {
  if (!calib.contains(key)) {
    if (fallback) return *fallback;
    throw py::value_error(std::string("calibration: missing '") + key + "'");
  }
  return real_arg(calib[key], std::string("calibration['") + key + "']", -1e12, 1e12);
}

OcamModel ocam_model(const py::dict& calib) {
  OcamModel m;
  if (!calib.contains("invpol")) throw py::value_error("calibration: missing 'invpol' (world2cam polynomial)");
  const py::array a = real_array(calib["invpol"], "calibration['invpol']");
  const auto v = a.cast<py::array_t<double, py::array::c_style | py::array::forcecast>>();
  m.invpol.assign(v.data(), v.data() + v.size());
  if (m.invpol.empty()) throw py::value_error("calibration['invpol']: no coefficients");
  for (const double x : m.invpol)
    if (!std::isfinite(x)) throw py::value_error("calibration['invpol']: coefficients must be finite");
  m.xc = calibration_number(calib, "xc");
  m.yc = calibration_number(calib, "yc");
  m.c = calibration_number(calib, "c", 1.0);
  m.d = calibration_number(calib, "d", 0.0);
  m.e = calibration_number(calib, "e", 0.0);
  return m;
}

/// OCamCalib's world2cam: the (row, column) position seeing camera-frame direction p (pixel centres at integers).
Vec2 ocam_world2cam(const OcamModel& m, const Vec3& p) {
  const double norm = std::sqrt(p.x * p.x + p.y * p.y);
  if (norm == 0.0) return Vec2(m.xc, m.yc);
  const double theta = std::atan(p.z / norm);
  double rho = 0.0, t_i = 1.0;
  for (const double a : m.invpol) {
    rho += a * t_i;
    t_i *= theta;
  }
  const double x = p.x / norm * rho, y = p.y / norm * rho;
  return Vec2(x * m.c + y * m.d + m.xc, x * m.e + y + m.yc);
}

/// A map of `kind` at natural size N whose texels see what the OCamCalib camera photographed: each texel centre's
/// direction goes through world2cam into the photograph, which is sampled there (bilinear by default). The camera
/// looks along view_dir with `roll`, as a fisheye view does; directions more than fov / 2 from its axis, or that
/// fall outside the photograph, get alpha 0 (coverage), never black light.
Ptr from_omnicam(const py::object& array, const py::dict& calib, const py::object& size_arg,
                 const std::string& parameterization, const py::object& view_dir, const py::object& roll,
                 const py::object& fov, const std::string& filter) {
  const OcamModel model = ocam_model(calib);
  const Image photo = image_from_array(array, "image");
  const int size = int_arg(size_arg, "size", 1, int(kMaxSizeArg));
  const Kind kind = parse_kind(parameterization);
  if (is_view_kind(kind)) throw py::value_error("parameterization: from_omnicam makes environment maps, not views");
  const Filter f = parse_filter(filter);
  if (f == Filter::Area) throw py::value_error("filter: the photograph is point-sampled: nearest, bilinear or bicubic");
  const ViewParams view = view_params(ViewArgs{py::none(), view_dir, roll, fov}, Kind::Fisheye).value_or([] {
    ViewParams v;
    v.fov_degrees = default_fov_degrees(Kind::Fisheye);
    return v;
  }());
  const ParamSpec spec = spec_for(kind, size, envkit::convention("envkit"));
  const int colour = photo.color_channels();
  const int channels = colour + 1;
  check_size_arg("size", kind_name(kind) + " map", spec.width, spec.height, double(channels) * sizeof(float));
  auto r = std::make_shared<PyEnvMap>();
  r->map.param = make_parameterization(spec);
  r->map.convention = "envkit";
  if (kind == Kind::CubeMap) r->layout = spec.layout;
  {
    py::gil_scoped_release release;
    Image out(spec.width, spec.height, channels);
    out.channel_names = default_channel_names(channels);
    out.alpha_channel = channels - 1;
    const ViewBasis b = view_basis(view);
    const double cos_half = std::cos(view.fov_degrees * kPi / 360.0);
    // The photograph as a plain image: a parameterization of its size whose taps stop at its edges.
    const PerspectiveMap plane(photo.width, photo.height, ViewParams{});
    const TexelSource source(photo, plane);
    const TexelDirections dirs(*r->map.param);
    const Mat3 to_world = r->map.to_world();
    parallel_chunks(std::size_t(spec.height), [&](std::size_t j0, std::size_t j1) {
      std::vector<float> s(std::size_t(photo.channels));
      for (std::size_t j = j0; j < j1; ++j)
        for (int i = 0; i < spec.width; ++i) {
          Vec3 d;
          if (!dirs.centre(i, int(j), d)) continue;
          d = apply(to_world, d).normalized();
          if ((d ^ b.forward) < cos_half) continue;
          const Vec3 cam(-(d ^ b.up), (d ^ b.right), -(d ^ b.forward));
          const Vec2 rc = ocam_world2cam(model, cam);
          const Vec2 pos(rc.y + 0.5, rc.x + 0.5);
          if (!(pos.x >= 0.0 && pos.y >= 0.0 && pos.x <= photo.width && pos.y <= photo.height)) continue;
          if (!source.sample(pos, f, s.data())) continue;
          float* o = out.at(i, int(j));
          int k = 0;
          for (int ch = 0; ch < photo.channels; ++ch)
            if (ch != photo.alpha_channel) o[k++] = s[std::size_t(ch)];
          o[channels - 1] = photo.alpha_channel >= 0 ? s[std::size_t(photo.alpha_channel)] : 1.0f;
        }
    });
    r->map.image = std::move(out);
  }
  return r;
}

}  // namespace

void bind_envmap_tools(py::module_& m) {
  auto cls = py::reinterpret_borrow<py::class_<PyEnvMap, Ptr>>(m.attr("EnvMap"));
  cls.def("image_coordinates", &image_coordinates,
          "(u, v): two H x W float64 arrays, the texel centres' image coordinates in [0, 1] ((i + 0.5) / W, "
          "(j + 0.5) / H), as skylibs' imageCoordinates().")
      .def("set_background", &set_background, py::arg("color"),
           "Sets every texel outside the map's coverage (its centre holds no data, or its alpha is 0) to `color` "
           "(a number, one value per colour channel, or one per channel), in place; returns the map.")
      .def("intensity", &intensity, py::arg("mode") = "bt709",
           "A one-channel map (Y, plus the alpha channel if any) of the colour channels' intensity: 'bt709' (the "
           "working space's luminance, Rec. 709: 0.2126 R + 0.7152 G + 0.0722 B), 'bt601' (0.299, 0.587, 0.114) "
           "or 'mean'.")
      .def("hemisphere", &hemisphere, py::arg("normal"),
           "H x W bool mask of the texels whose centre direction d (world, +Y up) has d . normal > 0.")
      .def("set_hemisphere", &set_hemisphere, py::arg("normal"), py::arg("value"),
           "Sets the texels of hemisphere(normal) to `value` (a number, one per colour channel, or one per "
           "channel), in place; returns the map.")
      .def("mean_light_vectors", &mean_light_vectors, py::arg("normals"), py::arg("mode") = "bt709",
           "skylibs' getMeanLightVectors for normals of shape (..., 3) -> (..., 3): (1 / Omega) sum over the "
           "texels with d . n > 0 of Y(d) d Omega(d), Y the intensity (mode as intensity()), Omega(d) the texel's "
           "solid angle and Omega their total (4 pi for a map of the whole sphere). Its component along n is the "
           "cosine-weighted integral of Y over the hemisphere, divided by Omega.")
      .def("blur", &blur, py::arg("kappa"),
           "The map convolved with the von Mises-Fisher lobe of concentration kappa >= 0 (larger: sharper; 0: the "
           "mean): texel x becomes sum_s L(s) w(s) / sum_s w(s), w(s) = Omega(s) exp(kappa (x . s - 1)), over "
           "every texel s of the map (a direct sum: time grows with the square of the texel count).")
      .def_static("from_omnicam", &from_omnicam, py::arg("image"), py::arg("calibration"), py::arg("size") = 512,
                  py::arg("parameterization") = "latlong", py::kw_only(), py::arg("view_dir") = py::none(),
                  py::arg("roll") = py::none(), py::arg("fov") = py::none(), py::arg("filter") = "bilinear",
                  R"(A map (parameterization at natural size N, envkit convention) from a photograph of an
OCamCalib-calibrated omnidirectional camera (Scaramuzza's polynomial model). calibration: a dict of
calib_results.txt's values: 'invpol' (world2cam coefficients, ascending powers), 'xc', 'yc' (the centre as row,
column; pixel centres at integers, as OCamCalib's C world2cam), 'c', 'd', 'e' (affine, default 1, 0, 0); 'pol'
is not needed. The camera looks along view_dir (default +Z) with roll, as a fisheye view; directions beyond
fov / 2 (default 180 degrees) from its axis or outside the photograph get alpha 0 (the output has an alpha
channel). Each texel centre is sampled (filter nearest, bilinear or bicubic).)");
}

}  // namespace envkit::python
