// envkit.render: a scene (the default, a JSON file, or JSON text from a dict)
// rendered with envrender's integrator; the mean image comes back as an H x W x
// 3 float32 array (no copy).
#include <envkit/env_sampling.h>
#include <envkit/error.h>
#include <envkit/render/integrator.h>
#include <envkit/render/render.h>
#include <envkit/render/scene_loader.h>
#include <pybind11/stl.h>

#include "arrays.h"
#include "bindings.h"

namespace envkit::python {

void bind_render(py::module_& m) {
  m.def(
      "_render",
      [](const std::optional<std::string>& path, const std::optional<std::string>& text, const std::string& base,
         int spp, const std::optional<std::string>& strategy, const std::string& light_method,
         const std::string& heuristic, std::optional<int> bsdf_samples, std::optional<int> light_samples,
         int sun_samples, int max_depth, std::uint32_t seed, int width, int height, bool bake,
         const std::optional<std::tuple<int, int, int, int>>& crop) {
        using namespace envkit::render;
        IntegratorOptions io;
        if (strategy) io.strategy = parse_strategy(*strategy);  // else the integrator's default
        io.light_method = parse_method(light_method);
        io.heuristic = parse_heuristic(heuristic);
        io.bsdf_samples = bsdf_samples;
        io.light_samples = light_samples;
        io.sun_samples = sun_samples;
        io.max_depth = max_depth;
        if (spp < 1) throw Error("render: spp must be >= 1");
        if (width < 0 || height < 0 || width > 16384 || height > 16384)
          throw Error("render: width and height must be in [1, 16384]");
        SceneLoadOptions load;
        load.bake = bake;
        load.width = width;
        load.height = height;
        Image image;
        {
          py::gil_scoped_release release;
          LoadedScene scene = path ? load_scene_file(*path, load)
                                   : (text ? load_scene_text(*text, base, load) : make_default_scene(load));
          const Integrator integrator(*scene.scene, *scene.light, io);
          RenderOptions ro;
          ro.spp = spp;
          ro.seed = seed;
          if (crop) ro.crop = Crop{std::get<0>(*crop), std::get<1>(*crop), std::get<2>(*crop), std::get<3>(*crop)};
          image = render_image(scene.camera, integrator, ro).mean_image();
        }
        return image_array(std::move(image));
      },
      py::arg("path"), py::arg("text"), py::arg("base"), py::arg("spp"), py::arg("strategy"), py::arg("light_method"),
      py::arg("heuristic"), py::arg("bsdf_samples"), py::arg("light_samples"), py::arg("sun_samples"),
      py::arg("max_depth"), py::arg("seed"), py::arg("width"), py::arg("height"), py::arg("bake"), py::arg("crop"));
}

}  // namespace envkit::python
