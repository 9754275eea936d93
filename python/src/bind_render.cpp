// envkit.render: a scene (the default, a JSON file, or JSON text from a dict)
// rendered with envrender's integrator; the mean image comes back as an H x W x
// 3 float32 array (no copy). envkit.farm's pieces: a loaded scene that renders
// windows of its image into the film's sums (_RenderJob), and the film of the
// whole assembled from those sums and written as envrender writes it
// (_write_film).
#include <envkit/core/atomic_file.h>
#include <envkit/core/error.h>
#include <envkit/envmap/envmap.h>
#include <envkit/io/request_limits.h>
#include <envkit/render/integrator.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <envkit/sampling/env_sampling.h>
#include <pybind11/stl.h>
#include <tbb/task_arena.h>

#include <map>
#include <memory>

#include "args.h"
#include "arrays.h"
#include "bindings.h"

namespace envkit::python {

namespace {

using namespace envkit::render;

// envrender's ranges (--resolution; 0: the scene's resolution) and its memory check of the image.
SceneLoadOptions load_options(const py::object& width, const py::object& height, bool bake) {
  SceneLoadOptions load;
  load.bake = bake;
  load.width = int_arg(width, "width", 0, 16384);
  load.height = int_arg(height, "height", 0, 16384);
  if (load.width > 0 && load.height > 0) {
    try {
      check_render_size(load.width, load.height);
    } catch (const RequestTooLarge& e) {
      throw py::value_error("width, height: " + std::string(e.what()));
    }
  }
  return load;
}

// envrender's --strategy, --light-method, --heuristic, --bsdf-samples, --light-samples, --sun-samples, --max-depth,
// --regularize.
IntegratorOptions integrator_options(const std::optional<std::string>& strategy, const std::string& light_method,
                                     const std::string& heuristic, const py::object& bsdf_samples,
                                     const py::object& light_samples, const py::object& sun_samples,
                                     const py::object& max_depth, const py::object& regularize) {
  IntegratorOptions io;
  if (strategy) io.strategy = parse_strategy(*strategy);  // else the integrator's default
  io.light_method = parse_method(light_method);
  io.heuristic = parse_heuristic(heuristic);
  io.bsdf_samples = optional_int_arg(bsdf_samples, "bsdf_samples", 0, 1024);
  io.light_samples = optional_int_arg(light_samples, "light_samples", 0, 1024);
  io.sun_samples = int_arg(sun_samples, "sun_samples", 0, 1024);
  io.max_depth = int_arg(max_depth, "max_depth", 1, 64);
  if (!regularize.is_none()) io.regularization = real_arg(regularize, "regularize", 0.0, 1e6);  // else the default
  return io;
}

Crop crop_arg(const py::object& crop) {
  if (!py::isinstance<py::sequence>(crop) || py::isinstance<py::str>(crop) || py::len(crop) != 4)
    throw py::type_error("crop: expected (x0, y0, x1, y1)");
  const py::sequence c = py::reinterpret_borrow<py::sequence>(crop);
  return Crop{int_arg(c[0], "crop", 0, 16384), int_arg(c[1], "crop", 0, 16384), int_arg(c[2], "crop", 0, 16384),
              int_arg(c[3], "crop", 0, 16384)};
}

// The scene from a file, JSON text (named `base` in messages) or the default; the loader's RequestTooLarge for the
// scene's camera resolution (or one side of it overridden) as ValueError.
LoadedScene load_scene(const std::optional<std::string>& path, const std::optional<std::string>& text,
                       const std::string& base, const SceneLoadOptions& load) {
  try {
    py::gil_scoped_release release;
    return path ? load_scene_file(*path, load) : (text ? load_scene_text(*text, base, load) : make_default_scene(load));
  } catch (const RequestTooLarge& e) {
    throw py::value_error((load.width > 0 || load.height > 0 ? "width, height: " : "scene: ") + std::string(e.what()));
  }
}

// A scene loaded once and its integrator, rendering any window of its image (a farm's tile) into the film's sums.
struct RenderJob {
  LoadedScene scene;
  IntegratorOptions options;
  std::unique_ptr<Integrator> integrator;
};

// The sums of a film as numpy arrays: sum and sum_sq (H, W, 3) float64, count (H, W) uint64.
py::dict film_sums(const Film& film) {
  const py::ssize_t h = film.height(), w = film.width();
  py::array_t<double> sum({h, w, py::ssize_t(3)}), sum_sq({h, w, py::ssize_t(3)});
  py::array_t<std::uint64_t> count({h, w});
  double* s = sum.mutable_data();
  double* q = sum_sq.mutable_data();
  std::uint64_t* n = count.mutable_data();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x, s += 3, q += 3, ++n) {
      const Film::Pixel& p = film.pixel(x, y);
      for (int c = 0; c < 3; ++c) {
        s[c] = p.sum[c];
        q[c] = p.sum_sq[c];
      }
      *n = p.count;
    }
  py::dict d;
  d["sum"] = sum;
  d["sum_sq"] = sum_sq;
  d["count"] = count;
  return d;
}

using SumArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using CountArray = py::array_t<std::uint64_t, py::array::c_style | py::array::forcecast>;

// A film of `crop` of a full_width x full_height image holding the given sums (shapes as film_sums gives them).
Film film_from_sums(int full_width, int full_height, const Crop& crop, const SumArray& sum, const SumArray& sum_sq,
                    const CountArray& count) {
  Film film(full_width, full_height, crop);
  const py::ssize_t h = film.height(), w = film.width();
  auto check = [&](const py::array& a, const char* name, bool rgb) {
    const bool ok = a.ndim() == (rgb ? 3 : 2) && a.shape(0) == h && a.shape(1) == w && (!rgb || a.shape(2) == 3);
    if (!ok)
      throw py::value_error(std::string(name) + ": expected shape (" + std::to_string(h) + ", " + std::to_string(w) +
                            (rgb ? ", 3)" : ")") + " for the crop");
  };
  check(sum, "sum", true);
  check(sum_sq, "sum_sq", true);
  check(count, "count", false);
  const double* s = sum.data();
  const double* q = sum_sq.data();
  const std::uint64_t* n = count.data();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x, s += 3, q += 3, ++n) {
      Film::Pixel& p = film.pixel(x, y);
      p.sum = Vec3(s[0], s[1], s[2]);
      p.sum_sq = Vec3(q[0], q[1], q[2]);
      p.count = *n;
    }
  return film;
}

void bind_farm(py::module_& m) {
  py::class_<RenderJob>(m, "_RenderJob")
      .def(py::init([](const std::optional<std::string>& path, const std::optional<std::string>& text,
                       const std::string& base, const std::optional<std::string>& strategy,
                       const std::string& light_method, const std::string& heuristic, const py::object& bsdf_samples,
                       const py::object& light_samples, const py::object& sun_samples, const py::object& max_depth,
                       const py::object& regularize, const py::object& width, const py::object& height, bool bake) {
             const IntegratorOptions io = integrator_options(strategy, light_method, heuristic, bsdf_samples,
                                                             light_samples, sun_samples, max_depth, regularize);
             auto job = std::make_unique<RenderJob>();
             job->scene = load_scene(path, text, base, load_options(width, height, bake));
             job->options = io;
             py::gil_scoped_release release;
             job->integrator =
                 std::make_unique<Integrator>(*job->scene.scene, *job->scene.light, io, &job->scene.camera);
             return job;
           }),
           py::arg("path"), py::arg("text"), py::arg("base"), py::arg("strategy"), py::arg("light_method"),
           py::arg("heuristic"), py::arg("bsdf_samples"), py::arg("light_samples"), py::arg("sun_samples"),
           py::arg("max_depth"), py::arg("regularize"), py::arg("width"), py::arg("height"), py::arg("bake"))
      .def_property_readonly("width", [](const RenderJob& j) { return j.scene.camera.width(); })
      .def_property_readonly("height", [](const RenderJob& j) { return j.scene.camera.height(); })
      .def_property_readonly("regularize", [](const RenderJob& j) { return j.options.regularization; })
      .def_property_readonly("environment", [](const RenderJob& j) { return j.scene.environment_description; })
      // The environment's image files (its faces for a '%' pattern): inputs an output must not replace.
      .def_property_readonly("environment_files",
                             [](const RenderJob& j) { return face_paths(j.scene.environment_description); })
      // The options' names as envrender records them in its EXR's metadata.
      .def("__repr__",
           [](const RenderJob& j) {
             return "<envkit._RenderJob " + std::to_string(j.scene.camera.width()) + "x" +
                    std::to_string(j.scene.camera.height()) + ", " + strategy_name(j.options.strategy) + ", " +
                    j.scene.environment_description + ">";
           })
      .def_property_readonly("strategy",
                             [](const RenderJob& j) { return std::string(strategy_name(j.options.strategy)); })
      .def_property_readonly("light_method",
                             [](const RenderJob& j) { return std::string(method_name(j.options.light_method)); })
      .def_property_readonly("has_sun_split", [](const RenderJob& j) { return j.integrator->sun_split() != nullptr; })
      .def_property_readonly("nonfinite_count", [](const RenderJob& j) { return j.integrator->nonfinite_count(); })
      // Renders the window crop = (x0, y0, x1, y1) with `threads` oneTBB threads (0: all) and returns its film's
      // sums (film_sums) with spp and seconds.
      .def(
          "render",
          [](const RenderJob& j, const py::object& crop, const py::object& spp, const py::object& seed,
             const py::object& threads) {
            RenderOptions ro;
            ro.spp = int_arg(spp, "spp", 1, 1 << 24);
            ro.seed = static_cast<std::uint32_t>(integer_arg(seed, "seed", 0, 0xffffffffLL));
            ro.crop = crop_arg(crop);
            const int n = int_arg(threads, "threads", 0, 4096);
            Film film;
            RenderStats stats;
            {
              py::gil_scoped_release release;
              tbb::task_arena arena(n > 0 ? n : tbb::task_arena::automatic);
              arena.execute([&] { film = render_image(j.scene.camera, *j.integrator, ro, &stats); });
            }
            py::dict d = film_sums(film);
            d["spp"] = stats.spp;
            d["seconds"] = stats.seconds;
            return d;
          },
          py::arg("crop"), py::arg("spp"), py::arg("seed"), py::arg("threads") = 0);

  // Writes the film of `crop` (of a full_width x full_height image) holding the given sums with envrender's
  // writer (Film::write_exr: the two-part EXR, metadata as string attributes), and its PNG preview when `preview`
  // names one; both files appear, or neither.
  m.def(
      "_write_film",
      [](const std::string& path, int full_width, int full_height, const py::object& crop, const SumArray& sum,
         const SumArray& sum_sq, const CountArray& count, const std::map<std::string, std::string>& metadata,
         const std::optional<std::string>& preview) {
        const Film film = film_from_sums(full_width, full_height, crop_arg(crop), sum, sum_sq, count);
        py::gil_scoped_release release;
        OutputGroup outputs;
        film.write_exr(path, metadata);
        if (preview) film.write_preview(*preview);
        outputs.commit();
      },
      py::arg("path"), py::arg("full_width"), py::arg("full_height"), py::arg("crop"), py::arg("sum"),
      py::arg("sum_sq"), py::arg("count"), py::arg("metadata"), py::arg("preview"));
  m.def("_default_scene_json", [] { return default_scene_json(); });
}

}  // namespace

void bind_render(py::module_& m) {
  m.def(
      "_render",
      [](const std::optional<std::string>& path, const std::optional<std::string>& text, const std::string& base,
         const py::object& spp, const std::optional<std::string>& strategy, const std::string& light_method,
         const std::string& heuristic, const py::object& bsdf_samples, const py::object& light_samples,
         const py::object& sun_samples, const py::object& max_depth, const py::object& seed, const py::object& width,
         const py::object& height, bool bake, const py::object& crop, const py::object& regularize) {
        RenderOptions ro;
        ro.spp = int_arg(spp, "spp", 1, 1 << 24);
        ro.seed = static_cast<std::uint32_t>(integer_arg(seed, "seed", 0, 0xffffffffLL));
        const SceneLoadOptions load = load_options(width, height, bake);
        if (!crop.is_none()) ro.crop = crop_arg(crop);
        const IntegratorOptions io = integrator_options(strategy, light_method, heuristic, bsdf_samples, light_samples,
                                                        sun_samples, max_depth, regularize);
        const LoadedScene scene = load_scene(path, text, base, load);
        Image image;
        {
          py::gil_scoped_release release;
          const Integrator integrator(*scene.scene, *scene.light, io, &scene.camera);
          image = render_image(scene.camera, integrator, ro).mean_image();
        }
        return image_array(std::move(image));
      },
      py::arg("path"), py::arg("text"), py::arg("base"), py::arg("spp"), py::arg("strategy"), py::arg("light_method"),
      py::arg("heuristic"), py::arg("bsdf_samples"), py::arg("light_samples"), py::arg("sun_samples"),
      py::arg("max_depth"), py::arg("seed"), py::arg("width"), py::arg("height"), py::arg("bake"), py::arg("crop"),
      py::arg("regularize"));
  m.attr("default_regularize") = IntegratorOptions{}.regularization;
  bind_farm(m);
}

}  // namespace envkit::python
