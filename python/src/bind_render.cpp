// envkit.render: a scene (the default, a JSON file, or JSON text from a dict)
// rendered with envrender's integrator; the mean image comes back as an H x W x
// 3 float32 array (no copy).
#include <envkit/core/error.h>
#include <envkit/io/request_limits.h>
#include <envkit/render/integrator.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <envkit/sampling/env_sampling.h>
#include <pybind11/stl.h>

#include "args.h"
#include "arrays.h"
#include "bindings.h"

namespace envkit::python {

void bind_render(py::module_& m) {
  m.def(
      "_render",
      [](const std::optional<std::string>& path, const std::optional<std::string>& text, const std::string& base,
         const py::object& spp, const std::optional<std::string>& strategy, const std::string& light_method,
         const std::string& heuristic, const py::object& bsdf_samples, const py::object& light_samples,
         const py::object& sun_samples, const py::object& max_depth, const py::object& seed, const py::object& width,
         const py::object& height, bool bake, const py::object& crop, const py::object& regularize) {
        using namespace envkit::render;
        // envrender's ranges (--spp, --bsdf-samples, --light-samples, --sun-samples, --max-depth, --seed,
        // --resolution; 0: the scene's resolution) and its memory check of the image.
        RenderOptions ro;
        ro.spp = int_arg(spp, "spp", 1, 1 << 24);
        ro.seed = static_cast<std::uint32_t>(integer_arg(seed, "seed", 0, 0xffffffffLL));
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
        if (!crop.is_none()) {
          if (!py::isinstance<py::sequence>(crop) || py::isinstance<py::str>(crop) || py::len(crop) != 4)
            throw py::type_error("crop: expected (x0, y0, x1, y1)");
          const py::sequence c = py::reinterpret_borrow<py::sequence>(crop);
          ro.crop = Crop{int_arg(c[0], "crop", 0, 16384), int_arg(c[1], "crop", 0, 16384),
                         int_arg(c[2], "crop", 0, 16384), int_arg(c[3], "crop", 0, 16384)};
        }
        IntegratorOptions io;
        if (strategy) io.strategy = parse_strategy(*strategy);  // else the integrator's default
        io.light_method = parse_method(light_method);
        io.heuristic = parse_heuristic(heuristic);
        io.bsdf_samples = optional_int_arg(bsdf_samples, "bsdf_samples", 0, 1024);
        io.light_samples = optional_int_arg(light_samples, "light_samples", 0, 1024);
        io.sun_samples = int_arg(sun_samples, "sun_samples", 0, 1024);
        io.max_depth = int_arg(max_depth, "max_depth", 1, 64);
        io.regularization = real_arg(regularize, "regularize", 0.0, 1e6);  // envrender's --regularize
        Image image;
        try {
          py::gil_scoped_release release;
          LoadedScene scene = path ? load_scene_file(*path, load)
                                   : (text ? load_scene_text(*text, base, load) : make_default_scene(load));
          const Integrator integrator(*scene.scene, *scene.light, io, &scene.camera);
          image = render_image(scene.camera, integrator, ro).mean_image();
        } catch (const RequestTooLarge& e) {
          // The scene's camera resolution (or one side of it overridden): the loader names the file and key.
          throw py::value_error((load.width > 0 || load.height > 0 ? "width, height: " : "scene: ") +
                                std::string(e.what()));
        }
        return image_array(std::move(image));
      },
      py::arg("path"), py::arg("text"), py::arg("base"), py::arg("spp"), py::arg("strategy"), py::arg("light_method"),
      py::arg("heuristic"), py::arg("bsdf_samples"), py::arg("light_samples"), py::arg("sun_samples"),
      py::arg("max_depth"), py::arg("seed"), py::arg("width"), py::arg("height"), py::arg("bake"), py::arg("crop"),
      py::arg("regularize"));
}

}  // namespace envkit::python
