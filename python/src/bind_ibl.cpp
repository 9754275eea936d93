// Real-time IBL from Python: the GGX radiance mip chain, the irradiance map, spherical harmonics and the DFG
// lookup table, each the libenv call envprefilter makes (prefilter.h, sh.h, dfg.h), written through the same
// writers (ibl_files.h), so arrays and files are envprefilter's bit for bit.
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/ibl/dfg.h>
#include <envkit/ibl/ibl_files.h>
#include <envkit/ibl/prefilter.h>
#include <envkit/ibl/sh.h>
#include <envkit/io/request_limits.h>
#include <envkit/maps/param_factory.h>
#include <envkit/maps/texel_directions.h>
#include <pybind11/stl.h>

#include <memory>
#include <optional>

#include "args.h"
#include "arrays.h"
#include "bindings.h"
#include "envmap_object.h"
#include "rotation_arg.h"
#include "view_args.h"

namespace envkit::python {

namespace {

/// A prefiltered chain (or the one-level irradiance map) and what writing it needs.
struct PyIbl {
  PrefilteredChain chain;  // an irradiance map is its one level (no roughness)
  Kind kind = Kind::CubeMap;
  bool irradiance = false;
  std::string source;  // envkit:source of the written files: the input's file name
};

Kind ibl_kind(bool octahedral) { return octahedral ? Kind::Octahedral : Kind::CubeMap; }

MapRef source_ref(const PyEnvMap& p, const py::object& rotate) {
  return MapRef{p.map.image, *p.map.param, rotated(p.map.to_world(), rotate)};
}

/// The number of levels of a full chain of level-0 side `size` (down to 1 x 1).
int full_levels(int size) {
  int n = 1;
  while ((size >> n) >= 1) ++n;
  return n;
}

std::shared_ptr<PyIbl> prefilter(const PyEnvMap& p, const py::object& size_arg, const py::object& levels_arg,
                                 const std::string& mapping, bool octahedral, const py::object& accuracy_arg,
                                 const py::object& rotate, const std::string& for_path) {
  // envprefilter's checks of --size, --levels and --accuracy.
  const int size = int_arg(size_arg, "size", 1, int(kMaxSizeArg));
  check_request_arg("size", [&] { check_prefilter_size(size, octahedral); });
  const int levels = int_arg(levels_arg, "levels", 0, full_levels(size));
  const double accuracy = real_arg(accuracy_arg, "accuracy", 0.01, 1.0);
  PrefilterOptions po;
  po.kind = ibl_kind(octahedral);
  po.size = size;
  po.levels = levels;
  po.mapping = argument_value([&] { return parse_roughness_mapping(mapping); });
  po.accuracy = accuracy;
  set_ibl_cube_faces(for_path, po);
  const MapRef src = source_ref(p, rotate);
  auto out = std::make_shared<PyIbl>();
  out->kind = po.kind;
  out->source = p.source;
  {
    py::gil_scoped_release release;
    out->chain = prefilter_ggx(src, po);
  }
  return out;
}

std::shared_ptr<PyIbl> irradiance(const PyEnvMap& p, const py::object& size_arg, bool octahedral,
                                  const py::object& accuracy_arg, bool divide_by_pi, const py::object& rotate) {
  // envprefilter's --irradiance-size and --accuracy checks.
  const int size = int_arg(size_arg, "size", 1, int(kMaxSizeArg));
  check_request_arg("size", [&] { check_irradiance_size(size, octahedral); });
  const double accuracy = real_arg(accuracy_arg, "accuracy", 0.01, 1.0);
  IrradianceOptions io;
  io.kind = ibl_kind(octahedral);
  io.size = size;
  io.accuracy = accuracy;
  io.divide_by_pi = divide_by_pi;
  const MapRef src = source_ref(p, rotate);
  auto out = std::make_shared<PyIbl>();
  out->kind = io.kind;
  out->irradiance = true;
  out->source = p.source;
  {
    py::gil_scoped_release release;
    out->chain.levels.push_back(irradiance_map(src, io));
  }
  return out;
}

/// Writes the chain (or irradiance map) as envprefilter -o (--irradiance) does. Every writer is atomic (temp file,
/// then rename); the group defers those renames so that all files of a chain appear together or none does.
void write(const PyIbl& ibl, const std::string& path, const std::string& format) {
  const GpuFormat f = argument_value([&] { return parse_gpu_format(format); });
  const std::vector<IblFile> files = ibl.irradiance
                                         ? std::vector<IblFile>{irradiance_file(path, ibl.chain.levels.at(0), ibl.kind)}
                                         : ggx_chain_files(path, ibl.chain, ibl.kind, ibl.source);
  std::vector<std::pair<ClampReport, std::string>> clamped;
  {
    py::gil_scoped_release release;
    file_operation([&] {
      OutputGroup group;
      for (const IblFile& file : files)
        clamped.emplace_back(write_ibl_file(file.path, file, ibl.kind == Kind::CubeMap, f), file.path);
      group.commit();
    });
  }
  for (const auto& [report, file] : clamped) warn_clamped(report, file);
}

py::array sh(const PyEnvMap& p, const py::object& order_arg, const std::string& kind, bool lambertian,
             const std::string& window, const py::object& rotate) {
  const int order = int_arg(order_arg, "order", 1, kMaxShOrder);  // envprefilter --sh-order
  if (kind != "radiance" && kind != "irradiance")
    throw ArgumentError("sh: kind must be radiance or irradiance, not " + kind);
  const ShWindow w = argument_value([&] { return parse_sh_window(window); });
  if (kind == "radiance" && (lambertian || w != ShWindow::None))
    throw ArgumentError(
        "sh: lambertian and window apply to irradiance (radiance coefficients are unwindowed, as in "
        "envprefilter's JSON)");
  const MapRef src = source_ref(p, rotate);
  ShCoefficients c;
  {
    py::gil_scoped_release release;
    c = project_sh(src, order, w);
  }
  const std::vector<std::vector<double>> v =
      kind == "radiance" ? c.radiance : (lambertian ? c.irradiance_over_pi() : c.irradiance());
  const py::ssize_t n = sh_count(order), channels = py::ssize_t(v.size());
  py::array_t<double> out({n, channels});
  auto o = out.mutable_unchecked<2>();
  for (py::ssize_t ch = 0; ch < channels; ++ch)
    for (py::ssize_t i = 0; i < n; ++i) o(i, ch) = v[ch][i];
  return out;
}

/// A map of `parameterization` at natural size N whose texels hold sum_i coeffs[i][c] Y_i(d) at their centre
/// direction d (world frame): SH coefficients (radiance, or irradiance) turned back into a map through libenv's
/// basis (sh_basis.h), truncated to `order` when given.
std::shared_ptr<PyEnvMap> sh_reconstruct(const py::object& coeffs_arg, const py::object& size_arg,
                                         const std::string& parameterization, const std::string& convention,
                                         const py::object& order_arg) {
  const py::array a = real_array(coeffs_arg, "coeffs");
  if (a.ndim() != 1 && a.ndim() != 2) throw py::value_error("coeffs: expected (n,) or (n, channels) coefficients");
  const auto c = a.cast<py::array_t<double, py::array::c_style | py::array::forcecast>>();
  const py::ssize_t n = c.shape(0), channels = a.ndim() == 2 ? c.shape(1) : 1;
  int full = 0;
  while (sh_count(full) < n && full < kMaxShOrder) ++full;
  if (sh_count(full) != n)
    throw py::value_error("coeffs: " + std::to_string(n) + " rows is not (order + 1)^2 for an order up to " +
                          std::to_string(kMaxShOrder));
  // Colour channels only, as EnvMap.sh returns them (alpha is never projected): Y or R, G, B.
  if (channels != 1 && channels != 3)
    throw py::value_error("coeffs: 1 or 3 colour channels (columns), got " + std::to_string(channels));
  const int order = order_arg.is_none() ? full : int_arg(order_arg, "order", 0, full);
  const int size = int_arg(size_arg, "size", 1, int(kMaxSizeArg));
  const Kind kind = argument_value([&] { return parse_kind(parameterization); });
  if (kind == Kind::Perspective || kind == Kind::Fisheye)
    throw ArgumentError("parameterization: sh_reconstruct makes environment maps, not camera views");
  const Convention& conv = argument_value([&]() -> const Convention& { return envkit::convention(convention); });
  const ParamSpec spec = spec_for(kind, size, conv);
  check_size_arg("size", kind_name(kind) + " map", spec.width, spec.height, double(channels) * sizeof(float));
  auto out = std::make_shared<PyEnvMap>();
  out->map.param = make_parameterization(spec);
  out->map.convention = conv.name;
  if (kind == Kind::CubeMap) out->layout = spec.layout;
  const double* cd = c.data();
  {
    py::gil_scoped_release release;
    Image img(spec.width, spec.height, int(channels));
    const TexelDirections dirs(*out->map.param);
    const Mat3 to_world = out->map.to_world();
    const int count = sh_count(order);
    parallel_chunks(std::size_t(spec.height), [&](std::size_t j0, std::size_t j1) {
      std::vector<double> y(static_cast<std::size_t>(count));
      for (std::size_t j = j0; j < j1; ++j)
        for (int i = 0; i < spec.width; ++i) {
          Vec3 d;
          if (!dirs.centre(i, int(j), d)) continue;
          sh_basis(order, apply(to_world, d).normalized(), y.data());
          float* px = img.at(i, int(j));
          for (py::ssize_t ch = 0; ch < channels; ++ch) {
            double v = 0.0;
            for (int k = 0; k < count; ++k) v += cd[k * channels + ch] * y[std::size_t(k)];
            px[ch] = float(v);
          }
        }
    });
    out->map.image = std::move(img);
  }
  return out;
}

}  // namespace

void bind_ibl(py::module_& m) {
  py::class_<PyIbl, std::shared_ptr<PyIbl>>(m, "PrefilteredChain", R"(A GGX radiance mip chain (EnvMap.prefilter) or
an irradiance map (EnvMap.irradiance): a sequence of H x W x C float32 arrays, level 0 first (cube: a vertical
strip of six faces in the GL basis, as the KTX2/DDS face table; octahedral: N x N). Arrays share the chain's
memory (no copy). write(path) writes what envprefilter -o (or --irradiance) writes.)")
      .def("__len__", [](const PyIbl& c) { return c.chain.levels.size(); })
      .def("__repr__",
           [](const PyIbl& c) {
             const Image& level0 = c.chain.levels.at(0).image;
             const std::string what = c.irradiance ? "irradiance map"
                                                   : std::to_string(c.chain.levels.size()) + " GGX levels, mapping " +
                                                         roughness_mapping_name(c.chain.mapping);
             return "<envkit.PrefilteredChain " + kind_name(c.kind) + ", " + what + ", level 0 " +
                    std::to_string(level0.width) + "x" + std::to_string(level0.height) + ">";
           })
      .def("__getitem__",
           [](py::object self, py::ssize_t k) {
             const PyIbl& c = self.cast<const PyIbl&>();
             const auto n = py::ssize_t(c.chain.levels.size());
             if (k < 0) k += n;
             if (k < 0 || k >= n) throw py::index_error("level " + std::to_string(k) + " of " + std::to_string(n));
             return image_view(c.chain.levels[std::size_t(k)].image, self);
           })
      .def_property_readonly(
          "levels",
          [](py::object self) {
            py::list out;
            for (const EnvMap& l : self.cast<const PyIbl&>().chain.levels) out.append(image_view(l.image, self));
            return out;
          },
          "The levels as a list of arrays (views of the chain's memory).")
      .def_property_readonly(
          "roughness", [](const PyIbl& c) { return c.chain.roughness; },
          "Perceptual roughness per level (empty for an irradiance map).")
      .def_property_readonly(
          "alpha", [](const PyIbl& c) { return c.chain.alpha; }, "GGX alpha = roughness^2 per level.")
      .def_property_readonly("mapping",
                             [](const PyIbl& c) -> py::object {
                               if (c.irradiance) return py::none();
                               return py::str(roughness_mapping_name(c.chain.mapping));
                             })
      .def_property_readonly("parameterization", [](const PyIbl& c) { return kind_name(c.kind); })
      .def_property_readonly("metadata", [](const PyIbl& c) { return c.chain.levels.at(0).image.metadata; })
      .def("write", &write, py::arg("path"), py::arg("format") = "rgba16f",
           R"(Writes the levels as envprefilter does, atomically: .ktx2 or .dds (every level in one file; format
rgba16f, rgba32f, rg11b10f or rgb9e5: only rgba32f holds a sun, the others clamp it with a UserWarning) or .exr
with '%' in the name (one float file per level, '%' -> 0, 1, ...; irradiance: one .exr).)");

  const char* prefilter_doc = R"(GGX radiance mip chain: envprefilter IN -o OUT [--size N] [--levels M]
[--mapping gltf|filament|unreal] [--octahedral] [--accuracy A] [--rotate R]. Level m has face size
max(1, size >> m) and roughness per the mapping; levels 0 = the full chain to 1 x 1. Returns a
PrefilteredChain (a sequence of arrays; .write(path) for KTX2, DDS, one EXR per level with '%' in the name, or one
mip-mapped OpenEXR cube for an .exr name without '%': that file holds OpenEXR's faces, so pass its path as for_path
here, as envprefilter -o name.exr does).)";
  m.def("prefilter", &prefilter, py::arg("map"), py::arg("size") = 256, py::arg("levels") = 0,
        py::arg("mapping") = "gltf", py::arg("octahedral") = false, py::arg("accuracy") = 0.2,
        py::arg("rotate") = py::none(), py::arg("for_path") = "", prefilter_doc);
  m.def("irradiance", &irradiance, py::arg("map"), py::arg("size") = 32, py::arg("octahedral") = false,
        py::arg("accuracy") = 0.2, py::arg("divide_by_pi") = true, py::arg("rotate") = py::none(),
        R"(Diffuse irradiance map: envprefilter IN --irradiance OUT [--irradiance-size N] [--octahedral]
[--accuracy A]. E/pi (the radiance a white Lambertian surface reflects) unless divide_by_pi=False. Returns a
one-level PrefilteredChain.)");
  m.def("sh", &sh, py::arg("map"), py::arg("order") = 2, py::arg("kind") = "radiance", py::arg("lambertian") = false,
        py::arg("window") = "none", py::arg("rotate") = py::none(),
        R"(Spherical harmonics (envprefilter --sh --sh-order --sh-window) of any order 1 .. 16: an
((order + 1)^2 x colour channels) float64 array, row i = l (l + 1) + m, real orthonormal basis without the Condon-Shortley phase (docs/PREFILTER.md).
kind 'radiance': L_lm (unwindowed, the JSON's radiance); 'irradiance': A_l w_l L_lm (the JSON's irradiance), or
with lambertian=True divided by pi (irradiance_over_pi). window: none, hanning, lanczos (irradiance only).)");
  m.def("sh_reconstruct", &sh_reconstruct, py::arg("coeffs"), py::arg("size") = 64,
        py::arg("parameterization") = "latlong", py::arg("convention") = "envkit", py::arg("order") = py::none(),
        R"(The map SH coefficients describe (skylibs' SphericalHarmonic.reconstruct): coeffs (n,) or (n, channels)
as EnvMap.sh returns them (rows i = l (l + 1) + m, n = (order + 1)^2, order up to 16), evaluated at every texel
centre of a `parameterization` map at natural size `size` (lat-long 2N x N) through libenv's basis (sh_basis.h):
texel = sum_i coeffs[i] Y_i(direction). Radiance coefficients give the band-limited radiance, irradiance ones
the irradiance (E, or E / pi for lambertian=True). order: keep bands 0 .. order only.)");
  // The same calls as methods of EnvMap (sky.prefilter(...), sky.sh(...)).
  auto envmap = py::reinterpret_borrow<py::class_<PyEnvMap, std::shared_ptr<PyEnvMap>>>(m.attr("EnvMap"));
  envmap.def("prefilter", &prefilter, py::arg("size") = 256, py::arg("levels") = 0, py::arg("mapping") = "gltf",
             py::arg("octahedral") = false, py::arg("accuracy") = 0.2, py::arg("rotate") = py::none(),
             py::arg("for_path") = "", prefilter_doc);
  envmap.def("irradiance", &irradiance, py::arg("size") = 32, py::arg("octahedral") = false, py::arg("accuracy") = 0.2,
             py::arg("divide_by_pi") = true, py::arg("rotate") = py::none(), "envkit.irradiance(self, ...).");
  envmap.def("sh", &sh, py::arg("order") = 2, py::arg("kind") = "radiance", py::arg("lambertian") = false,
             py::arg("window") = "none", py::arg("rotate") = py::none(), "envkit.sh(self, ...).");
  m.def(
      "dfg_lut",
      [](const py::object& size_arg, const std::string& layout) {
        const int size = int_arg(size_arg, "size", 1, int(kMaxSizeArg));
        check_request_arg("size", [&] { check_dfg_lut_size(size); });  // envprefilter --lut-size
        DfgOptions d;
        d.width = d.height = size;
        d.layout = argument_value([&] { return parse_dfg_layout(layout); });
        Image lut;
        {
          py::gil_scoped_release release;
          lut = dfg_lut(d);
        }
        return image_array(std::move(lut));
      },
      py::arg("size") = 128, py::arg("layout") = "scale-bias",
      R"(The split-sum DFG lookup table (envprefilter --lut --lut-size --lut-layout): size x size x 3 float32,
x = n.v, y = roughness (row 0 first); layout scale-bias (R = A, G = B, B = sheen) or filament (R = B, G = A + B).)");
}

}  // namespace envkit::python
