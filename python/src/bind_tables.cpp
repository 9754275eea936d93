// envkit.Tables: baking, loading and saving sampling tables, and vectorised
// sample / pdf / invert over arrays of any length. Each element is exactly
// SphericalDistribution::sample / pdf / invert (what envsample and envrender
// call), so results are bit-identical to the C++.
#include <envkit/core/error.h>
#include <envkit/io/request_limits.h>
#include <envkit/tables/env_tables.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <memory>
#include <span>

#include "args.h"
#include "arrays.h"
#include "bindings.h"
#include "envmap_object.h"

namespace envkit::python {

namespace {

using TablesPtr = std::shared_ptr<const EnvTables>;

TablesPtr bake(const PyEnvMap& map, const std::string& importance, const std::string& grid, const py::object& size_arg,
               const py::object& resolution_arg, const std::vector<std::string>& tables, bool conservative,
               const std::string& source_path, const std::string& source_hash) {
  const int size = int_arg(size_arg, "size", 0, int(kMaxSizeArg));  // 0: the natural grid
  std::optional<std::pair<int, int>> resolution;
  if (!resolution_arg.is_none()) resolution = int_pair_arg(resolution_arg, "resolution", 1, int(kMaxSizeArg));
  BakeOptions b;
  b.importance = argument_value([&] { return parse_importance(importance); });
  b.grid = argument_value([&] { return parse_kind(grid); });
  b.conservative = conservative;
  try {
    select_tables(tables, b);
  } catch (const Error& e) {
    throw ArgumentError(std::string("tables: ") + e.what());
  }
  if (resolution) {
    check_size_arg("resolution", "an importance map", resolution->first, resolution->second, kBakeBytesPerTexel);
    b.importance_width = resolution->first;
    b.importance_height = resolution->second;
  }
  if (size > 0) {
    // As envbake --size: N is the lat-long height, the octahedral side or the HEALPix N_side.
    b.height = b.grid == Kind::HEALPix ? 3 * size : size;
    b.width = b.grid == Kind::LatLong ? 2 * size : b.grid == Kind::HEALPix ? 4 * size : size;
    check_size_arg("size", "a bake grid", b.width, b.height, kBakeBytesPerTexel);
  }
  const std::string path = source_path.empty() ? map.name : source_path;
  py::gil_scoped_release release;
  // envbake records the hash of the source file's bytes; a map made in memory (named "<array>", "<probe>") is
  // hashed by its pixels.
  const bool in_memory = map.name.size() >= 2 && map.name.front() == '<' && map.name.back() == '>';
  std::string hash = source_hash;
  if (hash.empty()) hash = in_memory ? image_content_hash(map.map.image) : file_content_hash(face_paths(map.name));
  try {
    return std::make_shared<const EnvTables>(EnvTables::bake(map.map, b, path, hash));
  } catch (const Error& e) {
    // An importance resolution finer than the bake grid (known only once the grid is chosen) is a bad argument.
    if (resolution && std::string(e.what()).find("resolution") != std::string::npos)
      throw py::value_error(std::string("resolution: ") + e.what());
    throw;
  }
}

const SphericalDistribution& distribution(const EnvTables& t, const std::string& method, bool compensated,
                                          const std::string& name) {
  const SamplingMethod m = argument_value([&] { return parse_method(method); });
  const SphericalDistribution* d = t.distribution(m, compensated);
  if (!d)
    throw ArgumentError(name + ": has no " + table_name(m, compensated) + " table (re-bake with envbake --tables ...)");
  return *d;
}

struct PyTables {
  TablesPtr tables;
  std::string name;  // the file it was loaded from, or "<baked>"
};

/// An output array given by the caller: C-contiguous, writable, of the dtype and shape sample() would return.
template <class T>
py::array_t<T> output(const py::handle& given, const std::vector<py::ssize_t>& shape, const char* what) {
  if (!py::isinstance<py::array_t<T>>(given))
    throw ArgumentError(std::string("sample: out ") + what + " has the wrong dtype");
  py::array_t<T> a = py::reinterpret_borrow<py::array_t<T>>(given);
  const bool ok = a.ndim() == py::ssize_t(shape.size()) && std::equal(shape.begin(), shape.end(), a.shape()) &&
                  (a.flags() & py::array::c_style) && a.writeable();
  if (!ok)
    throw ArgumentError(std::string("sample: out ") + what +
                        " must be a writable C-contiguous array of the result's shape");
  return a;
}

py::tuple sample(const PyTables& t, const py::object& u_in, const std::string& method, bool compensated,
                 const py::object& out, bool batched) {
  const SphericalDistribution& d = distribution(*t.tables, method, compensated, t.name);
  std::size_t n = 0;
  const DoubleArray u = vectors(u_in, 2, "u", n);
  py::array_t<double> dirs, pdf;
  py::array_t<std::int32_t> texels;
  if (out.is_none()) {
    dirs = py::array_t<double>(result_shape(u, 3));
    pdf = py::array_t<double>(result_shape(u, 0));
    texels = py::array_t<std::int32_t>(result_shape(u, 2));
  } else {
    const py::tuple o = py::cast<py::tuple>(out);
    if (o.size() != 3) throw ArgumentError("sample: out must be (directions, pdf, texels)");
    dirs = output<double>(o[0], result_shape(u, 3), "directions");
    pdf = output<double>(o[1], result_shape(u, 0), "pdf");
    texels = output<std::int32_t>(o[2], result_shape(u, 2), "texels");
  }
  const double* ud = u.data();
  double* dd = dirs.mutable_data();
  double* pd = pdf.mutable_data();
  std::int32_t* td = texels.mutable_data();
  {
    py::gil_scoped_release release;
    const auto store = [&](std::size_t k, const DirectionSample& s) {
      dd[3 * k] = s.direction.x;
      dd[3 * k + 1] = s.direction.y;
      dd[3 * k + 2] = s.direction.z;
      pd[k] = s.pdf;
      td[2 * k] = s.x;
      td[2 * k + 1] = s.y;
    };
    parallel_chunks(n, [&](std::size_t k0, std::size_t k1) {
      if (!batched) {
        for (std::size_t k = k0; k < k1; ++k) store(k, d.sample(Vec2(ud[2 * k], ud[2 * k + 1])));
        return;
      }
      // The batched sample() (its table misses overlap), through blocks on the stack: u and the results are
      // copied between the arrays' layout and Vec2 / DirectionSample.
      constexpr std::size_t kBlock = 256;
      Vec2 ub[kBlock];
      DirectionSample sb[kBlock];
      for (std::size_t b = k0; b < k1; b += kBlock) {
        const std::size_t m = std::min(kBlock, k1 - b);
        for (std::size_t i = 0; i < m; ++i) ub[i] = Vec2(ud[2 * (b + i)], ud[2 * (b + i) + 1]);
        d.sample(std::span<const Vec2>(ub, m), std::span<DirectionSample>(sb, m));
        for (std::size_t i = 0; i < m; ++i) store(b + i, sb[i]);
      }
    });
  }
  return py::make_tuple(dirs, pdf, texels);
}

py::array pdf(const PyTables& t, const py::object& dir_in, const std::string& method, bool compensated) {
  const SphericalDistribution& d = distribution(*t.tables, method, compensated, t.name);
  std::size_t n = 0;
  const DoubleArray dirs = vectors(dir_in, 3, "directions", n);
  py::array_t<double> out(result_shape(dirs, 0));
  const double* in = dirs.data();
  double* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    parallel_chunks(n, [&](std::size_t k0, std::size_t k1) {
      for (std::size_t k = k0; k < k1; ++k) o[k] = d.pdf(Vec3(in[3 * k], in[3 * k + 1], in[3 * k + 2]));
    });
  }
  return out;
}

py::array invert(const PyTables& t, const py::object& dir_in, const std::string& method, bool compensated) {
  const SphericalDistribution& d = distribution(*t.tables, method, compensated, t.name);
  if (!d.can_invert())
    throw ArgumentError(t.name + ": the " +
                        std::string(method_name(argument_value([&] { return parse_method(method); }))) +
                        " table cannot be inverted (use cdf or hierarchical)");
  std::size_t n = 0;
  const DoubleArray dirs = vectors(dir_in, 3, "directions", n);
  py::array_t<double> out(result_shape(dirs, 2));
  const double* in = dirs.data();
  double* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    parallel_chunks(n, [&](std::size_t k0, std::size_t k1) {
      for (std::size_t k = k0; k < k1; ++k) {
        const Vec2 u = d.invert(Vec3(in[3 * k], in[3 * k + 1], in[3 * k + 2]));
        o[2 * k] = u.x;
        o[2 * k + 1] = u.y;
      }
    });
  }
  return out;
}

}  // namespace

void bind_tables(py::module_& m) {
  py::class_<PyTables, std::shared_ptr<PyTables>>(m, "Tables", R"(Baked importance-sampling tables (env_tables.h):
the importance map and the cdf / alias / hierarchical distributions over a lat-long, octahedral or HEALPix grid.
Directions are in the map's world frame (+Y up); pdf is per steradian.

Tables.bake(map, ...) bakes in memory (envbake); Tables.load(path) maps a .envtbl file (zero copy);
t.save(path) writes one.)")
      .def_static(
          "bake",
          [](const PyEnvMap& map, const std::string& importance, const std::string& grid, const py::object& size,
             const py::object& resolution, const std::vector<std::string>& tables, bool conservative,
             const std::string& source_path, const std::string& source_hash) {
            return std::make_shared<PyTables>(
                PyTables{bake(map, importance, grid, size, resolution, tables, conservative, source_path, source_hash),
                         "<baked>"});
          },
          py::arg("map"), py::arg("importance") = "luminance", py::arg("grid") = "latlong", py::arg("size") = 0,
          py::arg("resolution") = py::none(),
          py::arg("tables") = std::vector<std::string>{"cdf", "alias", "hierarchical"}, py::arg("conservative") = false,
          py::arg("source_path") = "", py::arg("source_hash") = "",
          R"(envbake: importance luminance|average|max, grid latlong|octahedral|healpix, size N (0: natural;
healpix: N_side, 4N x 3N),
resolution (W, H) of the importance, tables from cdf, alias, hierarchical, compensated, sun (the sun split of
each table, which rendering then reads instead of building it). The source hash is that of the file the map was
read from (as envbake records), or of the pixels for a map made from an array.)")
      .def_static(
          "load",
          [](const std::string& path, const std::string& expected_source_hash) {
            TablesPtr t;
            {
              py::gil_scoped_release release;
              t = std::make_shared<const EnvTables>(
                  file_operation([&] { return EnvTables::load(path, expected_source_hash); }));
            }
            return std::make_shared<PyTables>(PyTables{t, path});
          },
          py::arg("path"), py::arg("expected_source_hash") = "",
          "Loads a table file (checksums verified; stale when "
          "expected_source_hash is given and differs).")
      .def(
          "save",
          [](const PyTables& t, const std::string& path) {
            py::gil_scoped_release release;
            file_operation([&] { t.tables->save(path); });
          },
          py::arg("path"), "Writes the tables atomically.")
      .def("sample", &sample, py::arg("u"), py::arg("method") = "hierarchical", py::arg("compensated") = false,
           py::arg("out") = py::none(), py::arg("batched") = true,
           R"(Warps u of shape (..., 2) in [0, 1) to directions: returns (directions (..., 3), pdf (...),
texels (..., 2) int32 as (x, y) of the bake grid). out: those three arrays to fill instead of new ones (no
allocation and first touch of fresh memory per call in loops). batched=False calls the one-sample C++ sample() per
element instead of the batched one (the same results bit for bit, slower on large tables; for comparisons).)")
      .def("pdf", &pdf, py::arg("directions"), py::arg("method") = "hierarchical", py::arg("compensated") = false,
           "Density per steradian at directions (..., 3) -> (...).")
      .def("invert", &invert, py::arg("directions"), py::arg("method") = "hierarchical", py::arg("compensated") = false,
           "The u (..., 2) that sample() maps to directions (cdf, "
           "hierarchical).")
      .def_property_readonly(
          "importance",
          [](py::object self) {
            const EnvTables& t = *self.cast<PyTables&>().tables;
            const auto f = static_cast<py::ssize_t>(sizeof(float));
            const std::span<const float> imp = t.importance();
            py::array a(py::dtype::of<float>(), {py::ssize_t(t.height()), py::ssize_t(t.width())},
                        {py::ssize_t(t.width()) * f, f}, imp.data(), self);
            py::detail::array_proxy(a.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
            return a;
          },
          "Importance per texel (H x W float32, read-only view of the tables' "
          "memory).")
      .def("__repr__",
           [](const PyTables& t) {
             std::string methods;
             for (bool comp : {false, true})
               for (SamplingMethod sm : {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical})
                 if (t.tables->distribution(sm, comp))
                   methods += std::string(methods.empty() ? "" : ",") + table_name(sm, comp);
             return "<envkit.Tables " + kind_name(t.tables->grid()) + " " + std::to_string(t.tables->width()) + "x" +
                    std::to_string(t.tables->height()) + ", " + importance_name(t.tables->importance_mode()) +
                    ", tables " + methods + ", from " + t.name + ">";
           })
      .def_property_readonly("grid", [](const PyTables& t) { return kind_name(t.tables->grid()); })
      .def_property_readonly("width", [](const PyTables& t) { return t.tables->width(); })
      .def_property_readonly("height", [](const PyTables& t) { return t.tables->height(); })
      .def_property_readonly("importance_mode",
                             [](const PyTables& t) { return importance_name(t.tables->importance_mode()); })
      .def_property_readonly("total_importance", [](const PyTables& t) { return t.tables->total_importance(); })
      .def_property_readonly("source_path", [](const PyTables& t) { return t.tables->source_path(); })
      .def_property_readonly("source_hash", [](const PyTables& t) { return t.tables->source_hash(); })
      .def_property_readonly(
          "descriptor", [](const PyTables& t) { return t.tables->descriptor(); },
          "The JSON descriptor stored in the file (text).")
      .def_property_readonly("warnings",
                             [](const PyTables& t) {
                               std::vector<std::string> messages;
                               for (const TableWarning& w : t.tables->warnings()) messages.push_back(w.message);
                               return messages;
                             })
      .def_property_readonly("table_bytes", [](const PyTables& t) { return t.tables->table_bytes(); })
      .def(
          "methods",
          [](const PyTables& t) {
            std::vector<std::string> out;
            for (bool comp : {false, true})
              for (SamplingMethod sm : {SamplingMethod::Cdf, SamplingMethod::Alias, SamplingMethod::Hierarchical})
                if (t.tables->distribution(sm, comp)) out.push_back(table_name(sm, comp));
            return out;
          },
          "Baked tables, e.g. ['cdf', 'hierarchical', 'hierarchical-compensated'] (the names of table files' "
          "sections; sample(), pdf() and invert() take the method and compensated=True for a '-compensated' one).");

  m.def(
      "file_content_hash", [](const std::string& path) { return file_content_hash(face_paths(path)); }, py::arg("path"),
      "XXH3-128 of the file's bytes (six faces for a '%' pattern), as envbake "
      "records it.");
}

}  // namespace envkit::python
