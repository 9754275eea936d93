#pragma once
/// @file scene_loader.h
/// JSON scenes (docs/SCENE_FORMAT.md) and the built-in default scene.
///
/// Errors are envkit::Error with one line "<file>:<line>: <key path>: <problem>", e.g.
/// "scene.json:14: shapes[2].material: unknown material 'gold' (defined: ground, red)". Malformed JSON reports
/// the parser's line. Unknown keys, unknown material types and names, missing or unreadable meshes, degenerate
/// triangles, a camera inside geometry and missing or stale table files (unless bake) are errors.
#include <envkit/envmap/envmap.h>
#include <envkit/render/camera.h>
#include <envkit/render/env_light.h>
#include <envkit/render/scene.h>
#include <envkit/tables/env_tables.h>

#include <memory>
#include <string>
#include <vector>

namespace envkit::render {

struct SceneLoadOptions {
  bool bake = false;  ///< bake missing/stale tables in memory instead of failing
  /// Camera resolution override (0 = the file's).
  int width = 0, height = 0;
};

/// Memory a render holds per image pixel: the film's sums (two Vec3 and a count), the mean image and the output
/// buffers written from it.
inline constexpr double kRenderBytesPerPixel = 112.0;
/// envkit::check_request_size (request_limits.h) for a width x height render: throws RequestTooLarge
/// ("a render of W x H needs about X GiB ..."). The loaders call it on the final camera resolution (the file's or
/// the override) before the environment or any mesh is loaded.
void check_render_size(int width, int height);

struct LoadedScene {
  std::unique_ptr<Scene> scene;
  Camera camera;
  std::shared_ptr<const EnvTables> tables;
  std::unique_ptr<EnvironmentLight> light;
  std::string environment_description;
  std::vector<std::string> notes;  ///< lines for the user (e.g. "baked tables in memory")
};

/// Loads a scene file; relative paths inside it are relative to the file's directory.
LoadedScene load_scene_file(const std::string& path, const SceneLoadOptions& options = {});
/// Loads a scene from JSON text; `path` names it in messages and gives the base directory.
LoadedScene load_scene_text(const std::string& text, const std::string& path, const SceneLoadOptions& options = {});

/// One material as a scene file's `materials` entry gives it (docs/SCENE_FORMAT.md), from the JSON text of that
/// entry; `source` names the text in messages ("<source>:<line>: material.<key>: <problem>", the scene's errors) and
/// its directory resolves relative file names (a measured material's `file`).
std::unique_ptr<Material> load_material_text(const std::string& text, const std::string& source);

/// The light of a scene's `environment` entry alone (docs/SCENE_FORMAT.md), from the JSON text of that entry:
/// the LoadedScene without scene and camera. Errors as the scene's ("<source>:<line>: environment.<key>: ...").
LoadedScene load_environment_text(const std::string& text, const std::string& source,
                                  const SceneLoadOptions& options = {});

/// The built-in default scene: a row of five spheres of increasing roughness (rough plastic and conductor,
/// alpha 0.01 .. 0.5) on a diffuse ground plane plus a diffuse sphere, lit by the built-in default probe
/// (envkit::probes::make_default_probe(), 1024x512, tables baked in memory). Same as renderer/scenes/default.json.
LoadedScene make_default_scene(const SceneLoadOptions& options = {});
/// The JSON text of the default scene.
const std::string& default_scene_json();

}  // namespace envkit::render
