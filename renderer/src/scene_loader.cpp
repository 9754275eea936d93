#include <envkit/core/error.h>
#include <envkit/core/excerpt.h>
#include <envkit/core/input_checks.h>
#include <envkit/io/color.h>
#include <envkit/io/request_limits.h>
#include <envkit/maps/convention.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <envkit/render/material.h>
#include <envkit/render/scene_loader.h>
#include <tiny_obj_loader.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "json_lines.h"

namespace envkit::render {

namespace {

// The supported range of scene geometry, in scene units: coordinates within +-1e6, sphere radii in [1e-4, 1e6].
// Ray offsets (1e-6 relative) and the float meshes keep intersections exact to ~1e-6 of the scene's extent.
constexpr double kMaxSceneCoordinate = 1e6;
constexpr double kMinSphereRadius = 1e-4;
// Longest file name a message echoes whole (longer ones are cut, see excerpt()).
constexpr std::size_t kPathChars = 200;

/// A key path ("materials.<name>.roughness") as shown in a message: each part between dots cut by excerpt(), so a
/// 2 MB key or material name cannot make a 2 MB message, while the parts after it still show.
std::string shown_field(const std::string& path) {
  std::string out;
  std::size_t from = 0;
  for (;;) {
    const std::size_t dot = path.find('.', from);
    out += excerpt(std::string_view(path).substr(from, dot == std::string::npos ? std::string::npos : dot - from));
    if (dot == std::string::npos) return out;
    out += '.';
    from = dot + 1;
  }
}

/// A file name from the scene as shown in a message.
std::string shown_path(const std::string& file) {
  std::string shown = excerpt(file, kPathChars);
  shown.insert(shown.begin(), '\'');
  shown.push_back('\'');
  return shown;
}

using nlohmann::json;

/// Reads typed values out of the JSON and reports problems as "<file>:<line>: <path>: <problem>".
class Reader {
 public:
  Reader(const LineTrackedJson& doc, std::string file) : doc_(doc), file_(std::move(file)) {}

  [[noreturn]] void fail(const std::string& path, const std::string& problem) const {
    throw Error(file_ + ":" + std::to_string(doc_.line_of(path)) + ": " +
                (path.empty() ? "" : shown_field(path) + ": ") + problem);
  }

  static std::string join(const std::string& path, const std::string& key) {
    return path.empty() ? key : path + "." + key;
  }

  /// Fails on keys outside `allowed`.
  void check_keys(const json& object, const std::string& path, const std::set<std::string>& allowed) const {
    if (!object.is_object()) fail(path, "expected an object");
    for (const auto& [key, value] : object.items())
      if (!allowed.count(key)) {
        std::string list;
        for (const auto& k : allowed) list += (list.empty() ? "" : ", ") + k;
        fail(join(path, key), "unknown key '" + excerpt(key) + "' (valid: " + list + ")");
      }
  }
  const json& require(const json& object, const std::string& path, const std::string& key) const {
    if (!object.contains(key)) fail(join(path, key), "missing key '" + key + "'");  // the line of `path`
    return object.at(key);
  }
  double number(const json& v, const std::string& path) const {
    if (!v.is_number()) fail(path, "expected a number");
    const double d = v.get<double>();
    if (!std::isfinite(d)) fail(path, "expected a finite number");
    return d;
  }
  double number(const json& object, const std::string& path, const std::string& key, double fallback) const {
    return object.contains(key) ? number(object.at(key), join(path, key)) : fallback;
  }
  int integer(const json& v, const std::string& path) const {
    if (!v.is_number_integer()) fail(path, "expected an integer");
    return v.get<int>();
  }
  std::string string(const json& v, const std::string& path) const {
    if (!v.is_string()) fail(path, "expected a string");
    return v.get<std::string>();
  }
  /// A file name: a non-empty string without NUL characters (no file system takes them; cut at the NUL, the name
  /// would silently name another file).
  std::string file_name(const json& v, const std::string& path) const {
    const std::string name = string(v, path);
    if (name.empty()) fail(path, "empty file name");
    if (name.find('\0') != std::string::npos)
      fail(path, "file name " + shown_path(name) + " contains a NUL character (\\u0000)");
    return name;
  }
  std::vector<double> numbers(const json& v, const std::string& path, std::size_t n) const {
    if (!v.is_array() || v.size() != n) fail(path, "expected an array of " + std::to_string(n) + " numbers");
    std::vector<double> out;
    for (std::size_t i = 0; i < n; ++i) out.push_back(number(v[i], path + "[" + std::to_string(i) + "]"));
    return out;
  }
  Vec3 vec3(const json& v, const std::string& path) const {
    const auto n = numbers(v, path, 3);
    return Vec3(n[0], n[1], n[2]);
  }
  /// A point of the scene: every coordinate within +-kMaxSceneCoordinate (docs/SCENE_FORMAT.md).
  Vec3 point(const json& v, const std::string& path) const {
    const Vec3 p = vec3(v, path);
    check_point(p, path);
    return p;
  }
  void check_point(const Vec3& p, const std::string& path) const {
    for (int i = 0; i < 3; ++i)
      if (!(std::abs(p[i]) <= kMaxSceneCoordinate))
        fail(path, "coordinates must be within +-1e6 scene units (the supported range)");
  }
  Vec3 vec3(const json& object, const std::string& path, const std::string& key, const Vec3& fallback) const {
    return object.contains(key) ? vec3(object.at(key), join(path, key)) : fallback;
  }
  /// A colour: [r, g, b] or one number (grey); every channel >= 0.
  Vec3 colour(const json& object, const std::string& path, const std::string& key, const Vec3& fallback,
              double max_value = 1e30) const {
    if (!object.contains(key)) return fallback;
    const json& v = object.at(key);
    const std::string p = join(path, key);
    const Vec3 c = v.is_number() ? Vec3(number(v, p)) : vec3(v, p);
    for (int i = 0; i < 3; ++i)
      if (c[i] < 0.0 || c[i] > max_value)
        fail(p, "colour components must be in [0, " + std::to_string(max_value) + "]");
    return c;
  }

  const std::string& file() const { return file_; }

 private:
  const LineTrackedJson& doc_;
  std::string file_;
};

std::string resolve(const std::string& base_dir, const std::string& relative) {
  if (relative.empty() || std::filesystem::path(relative).is_absolute() || base_dir.empty()) return relative;
  return (std::filesystem::path(base_dir) / relative).lexically_normal().string();
}

void require_scene_file(const Reader& r, const std::string& path, const std::string& file, const std::string& what);

std::unique_ptr<Material> parse_material(const Reader& r, const json& m, const std::string& path,
                                         const std::string& base_dir) {
  if (!m.is_object()) r.fail(path, "expected an object");
  const std::string type = r.string(r.require(m, path, "type"), Reader::join(path, "type"));
  if (type == "diffuse") {
    r.check_keys(m, path, {"type", "albedo"});
    return make_diffuse(r.colour(m, path, "albedo", Vec3(0.5), 1.0));
  }
  if (type == "conductor") {
    r.check_keys(m, path, {"type", "eta", "k", "roughness", "shadowing"});
    const double roughness = r.number(m, path, "roughness", 0.1);
    if (!(roughness > 0.0 && roughness <= 1.0)) r.fail(Reader::join(path, "roughness"), "must be in (0, 1]");
    Shadowing shadowing = Shadowing::HeightCorrelated;
    if (m.contains("shadowing")) {
      const std::string name = r.string(m["shadowing"], Reader::join(path, "shadowing"));
      if (name == shadowing_name(Shadowing::Separable))
        shadowing = Shadowing::Separable;
      else if (name != shadowing_name(Shadowing::HeightCorrelated))
        r.fail(Reader::join(path, "shadowing"),
               "unknown value '" + excerpt(name) + "' (valid: height-correlated, separable)");
    }
    // Default: gold (eta, k at ~630/532/465 nm).
    return make_conductor(r.colour(m, path, "eta", Vec3(0.143, 0.374, 1.442)),
                          r.colour(m, path, "k", Vec3(3.983, 2.386, 1.603)), roughness, shadowing);
  }
  if (type == "plastic") {
    r.check_keys(m, path, {"type", "diffuse", "roughness", "ior"});
    const double roughness = r.number(m, path, "roughness", 0.1);
    if (!(roughness > 0.0 && roughness <= 1.0)) r.fail(Reader::join(path, "roughness"), "must be in (0, 1]");
    const double ior = r.number(m, path, "ior", 1.5);
    if (!(ior > 1.0 && ior < 4.0)) r.fail(Reader::join(path, "ior"), "must be in (1, 4)");
    return make_plastic(r.colour(m, path, "diffuse", Vec3(0.5), 1.0), roughness, ior);
  }
  if (type == "mirror") {
    r.check_keys(m, path, {"type", "reflectance"});
    return make_mirror(r.colour(m, path, "reflectance", Vec3(1.0), 1.0));
  }
  if (type == "measured") {
    r.check_keys(m, path, {"type", "file", "scale"});
    const std::string field = Reader::join(path, "file");
    const std::string file = resolve(base_dir, r.file_name(r.require(m, path, "file"), field));
    require_scene_file(r, field, file, "MERL BRDF file");
    const Vec3 scale = r.colour(m, path, "scale", Vec3(1.0), 1e6);
    try {
      return make_measured(file, scale);
    } catch (const Error& err) {
      r.fail(field, err.what());
    }
  }
  r.fail(Reader::join(path, "type"),
         "unknown material type '" + excerpt(type) + "' (valid: diffuse, conductor, plastic, mirror, measured)");
}

/// Fails unless `file` is a regular file (a FIFO or device would block or never end), naming the scene, the line, the
/// field and the file; `what` says what the file is for ("mesh file").
void require_scene_file(const Reader& r, const std::string& path, const std::string& file, const std::string& what) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(file, ec);
  if (st.type() == std::filesystem::file_type::not_found)
    r.fail(path, what + " " + shown_path(file) + " does not exist");
  if (ec) r.fail(path, what + " " + shown_path(file) + ": " + ec.message());  // a symlink loop, a denied directory
  if (std::filesystem::is_directory(st)) r.fail(path, what + " " + shown_path(file) + " is a directory");
  try {
    require_regular_file(file);
  } catch (const Error& err) {
    r.fail(path, err.what());
  }
}

TriangleMesh load_obj(const std::string& file, const Reader& r, const std::string& path) {
  require_scene_file(r, path, file, "mesh file");
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(file, config)) {
    std::string message = reader.Error();
    while (!message.empty() && (message.back() == '\n' || message.back() == '\r')) message.pop_back();
    if (const auto nl = message.find('\n'); nl != std::string::npos) message.resize(nl);
    r.fail(path, file + ": cannot read OBJ: " + (message.empty() ? "parse error" : message));
  }
  const auto& attrib = reader.GetAttrib();
  TriangleMesh mesh;
  bool all_normals = true;
  std::vector<Vec3> normals;
  for (const auto& shape : reader.GetShapes())
    for (std::size_t i = 0; i + 2 < shape.mesh.indices.size() + 0; i += 3) {
      std::array<int, 3> tri{};
      for (int k = 0; k < 3; ++k) {
        const tinyobj::index_t idx = shape.mesh.indices[i + std::size_t(k)];
        if (idx.vertex_index < 0 || 3 * std::size_t(idx.vertex_index) + 2 >= attrib.vertices.size())
          r.fail(path, file + ": face with an invalid vertex index");
        const float* v = &attrib.vertices[3 * std::size_t(idx.vertex_index)];
        tri[std::size_t(k)] = int(mesh.positions.size());
        mesh.positions.emplace_back(v[0], v[1], v[2]);
        if (idx.normal_index >= 0 && 3 * std::size_t(idx.normal_index) + 2 < attrib.normals.size()) {
          const float* n = &attrib.normals[3 * std::size_t(idx.normal_index)];
          normals.emplace_back(n[0], n[1], n[2]);
        } else {
          all_normals = false;
          normals.emplace_back(0, 0, 0);
        }
      }
      mesh.triangles.push_back(tri);
    }
  if (mesh.triangles.empty()) r.fail(path, file + ": the OBJ file has no faces");
  if (all_normals) mesh.normals = std::move(normals);
  return mesh;
}

/// The environment map of a "probe" entry, rasterized onto an envkit lat-long.
EnvMap make_probe_map(const Reader& r, const json& e, const std::string& path, std::string& description) {
  const std::string kind = r.string(e.at("probe"), Reader::join(path, "probe"));
  int width = 1024, height = 512;
  if (e.contains("size")) {
    const auto s = r.numbers(e.at("size"), Reader::join(path, "size"), 2);
    width = int(s[0]);
    height = int(s[1]);
    if (width < 4 || height < 2 || width > 16384 || height > 8192 || width != s[0] || height != s[1])
      r.fail(Reader::join(path, "size"), "expected two integers, 4..16384 x 2..8192");
  }
  std::unique_ptr<probes::Probe> probe;
  if (kind == "default") {
    probe = probes::make_default_probe();
  } else if (kind == "overcast") {
    probes::OutdoorSettings settings;
    settings.cloud_cover = 1.0;
    settings.sun_radiance = Vec3(0, 0, 0);
    probe = std::make_unique<probes::OutdoorProbe>(settings);
  } else if (kind == "constant") {
    probe = std::make_unique<probes::ConstantProbe>(r.colour(e, path, "radiance", Vec3(1.0)));
  } else if (kind == "sun") {
    const double elevation = r.number(e, path, "elevation_deg", 45.0);
    const double azimuth = r.number(e, path, "azimuth_deg", 30.0);
    const double radius = r.number(e, path, "radius_deg", 0.27);
    if (!(radius > 0.0 && radius <= 90.0)) r.fail(Reader::join(path, "radius_deg"), "must be in (0, 90]");
    probe = std::make_unique<probes::SunProbe>(
        probes::direction_from_elevation_azimuth(probes::radians(elevation), probes::radians(azimuth)),
        probes::radians(radius), r.colour(e, path, "radiance", Vec3(1e5)), r.colour(e, path, "sky", Vec3(0.5)));
  } else {
    r.fail(Reader::join(path, "probe"),
           "unknown probe '" + excerpt(kind) + "' (valid: default, overcast, constant, sun)");
  }
  description = "probe " + probe->describe();
  // Built directly: any W x H lat-long is a valid bake grid (make_envmap would insist on a 2:1 image file).
  EnvMap env;
  env.param = std::make_unique<LatLongMap>(width, height);
  env.image = probes::rasterize(*probe, *env.param);
  return env;
}

const std::set<std::string> kEnvironmentKeys = {"image",      "tables",   "probe",         "size",
                                                "radiance",   "sky",      "elevation_deg", "azimuth_deg",
                                                "radius_deg", "rotation", "intensity",     "convention"};

void load_environment(const Reader& r, const json& e, const std::string& base_dir, const SceneLoadOptions& options,
                      LoadedScene& out) {
  const std::string path = "environment";
  r.check_keys(e, path, kEnvironmentKeys);
  const bool has_image = e.contains("image"), has_probe = e.contains("probe");
  if (has_image == has_probe) r.fail(path, "give exactly one of 'image' and 'probe'");
  Mat3 rotation = identity3();
  if (e.contains("rotation")) {
    const auto a = r.numbers(e.at("rotation"), "environment.rotation", 3);
    rotation = rotation_from_euler_degrees(a[0], a[1], a[2]);
  }
  const double intensity = r.number(e, path, "intensity", 1.0);
  if (!(intensity >= 0.0)) r.fail("environment.intensity", "must be >= 0");

  EnvMap map;
  std::string image_path, tables_path;
  bool bake = options.bake;
  if (has_probe) {
    map = make_probe_map(r, e, path, out.environment_description);
    bake = true;  // generated in memory: nothing on disk to be stale
    if (e.contains("tables")) r.fail("environment.tables", "a probe environment is baked in memory; remove 'tables'");
  } else {
    for (const char* key : {"size", "radiance", "sky", "elevation_deg", "azimuth_deg", "radius_deg"})
      if (e.contains(key)) r.fail(Reader::join(path, key), "only valid with 'probe'");
    image_path = resolve(base_dir, r.file_name(e.at("image"), "environment.image"));
    if (e.contains("tables")) tables_path = resolve(base_dir, r.file_name(e.at("tables"), "environment.tables"));
    LoadOptions load;
    if (e.contains("convention")) {
      const std::string name = r.string(e.at("convention"), "environment.convention");
      try {
        load.convention = &convention(name);
      } catch (const Error& err) {
        r.fail("environment.convention", err.what());
      }
    }
    try {
      map = load_envmap(image_path, load);
    } catch (const Error& err) {
      r.fail("environment.image", err.what());
    } catch (const std::filesystem::filesystem_error& err) {
      r.fail("environment.image", shown_path(image_path) + ": " + err.code().message());
    }
    out.environment_description = image_path;
    if (!bake && tables_path.empty())
      r.fail(path, "no 'tables' file for " + image_path + " (bake one with envbake, or pass --bake to bake in memory)");
  }
  const std::string tables_field = has_probe ? "environment" : "environment.tables";
  try {
    std::string note;
    out.tables = load_or_bake_tables(map, has_probe ? std::string() : image_path, tables_path, bake, &note);
    if (!note.empty())
      out.notes.push_back((has_probe ? "probe '" + e.at("probe").get<std::string>() + "': " : std::string()) + note);
  } catch (const Error& err) {
    r.fail(tables_field, err.what());
  } catch (const std::filesystem::filesystem_error& err) {
    r.fail(tables_field, shown_path(tables_path) + ": " + err.code().message());
  }
  out.light = std::make_unique<EnvironmentLight>(map, out.tables, rotation, intensity);
}

}  // namespace

LoadedScene load_scene_text(const std::string& text, const std::string& file, const SceneLoadOptions& options) {
  const LineTrackedJson doc = parse_json_with_lines(text, file);
  const Reader r(doc, file);
  const json& root = doc.value;
  r.check_keys(root, "", {"camera", "environment", "materials", "shapes"});
  const std::string base_dir = std::filesystem::path(file).parent_path().string();
  LoadedScene out;

  // Camera
  const json& c = r.require(root, "", "camera");
  r.check_keys(c, "camera", {"position", "look_at", "up", "fov", "resolution"});
  const Vec3 position = r.point(r.require(c, "camera", "position"), "camera.position");
  const Vec3 look_at = r.point(r.require(c, "camera", "look_at"), "camera.look_at");
  const Vec3 up = r.vec3(c, "camera", "up", Vec3(0, 1, 0));
  const double fov = r.number(c, "camera", "fov", 40.0);
  int width = 480, height = 270;
  if (c.contains("resolution")) {
    const auto& res = c.at("resolution");
    if (!res.is_array() || res.size() != 2) r.fail("camera.resolution", "expected [width, height]");
    width = r.integer(res[0], "camera.resolution[0]");
    height = r.integer(res[1], "camera.resolution[1]");
    if (width < 1 || height < 1 || width > 16384 || height > 16384) r.fail("camera.resolution", "must be 1..16384");
  }
  if (options.width > 0) width = options.width;
  if (options.height > 0) height = options.height;
  try {
    check_render_size(width, height);
  } catch (const RequestTooLarge& e) {
    // Still a RequestTooLarge, now naming the scene file and the key: callers map it to their option or argument.
    const std::string where = file + ":" + std::to_string(doc.line_of("camera.resolution")) + ": camera.resolution: ";
    throw RequestTooLarge(where + e.what(), e.requested(), e.width(), e.height(), e.bytes_needed());
  }
  try {
    out.camera = Camera(position, look_at, up, fov, width, height);
  } catch (const Error& err) {
    r.fail("camera", err.what());
  }

  // Materials
  out.scene = std::make_unique<Scene>();
  const json& materials = r.require(root, "", "materials");
  if (!materials.is_object() || materials.empty()) r.fail("materials", "expected an object of named materials");
  for (const auto& [name, m] : materials.items())
    out.scene->add_material(name, parse_material(r, m, "materials." + name, base_dir));

  // Shapes
  const json& shapes = r.require(root, "", "shapes");
  if (!shapes.is_array() || shapes.empty()) r.fail("shapes", "expected a non-empty array");
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    const std::string path = "shapes[" + std::to_string(i) + "]";
    const json& s = shapes[i];
    if (!s.is_object()) r.fail(path, "expected an object");
    const std::string type = r.string(r.require(s, path, "type"), path + ".type");
    const std::string material_name = r.string(r.require(s, path, "material"), path + ".material");
    const int material = out.scene->find_material(material_name);
    if (material < 0) {
      std::string list;
      for (const auto& n : out.scene->material_names()) list += (list.empty() ? "" : ", ") + n;
      r.fail(path + ".material",
             "unknown material '" + excerpt(material_name) + "' (defined: " + excerpt(list, 200) + ")");
    }
    if (type == "sphere") {
      r.check_keys(s, path, {"type", "material", "center", "radius"});
      const Vec3 centre = r.point(r.require(s, path, "center"), path + ".center");
      const double radius = r.number(r.require(s, path, "radius"), path + ".radius");
      // The supported range: ray offsets are relative to 1 scene unit and the hit position, so a sphere far
      // smaller or larger than the scene's unit is lost to rounding (it would silently vanish).
      if (!(radius >= kMinSphereRadius && radius <= kMaxSceneCoordinate))
        r.fail(path + ".radius", "must be in [1e-4, 1e6] scene units (the supported range)");
      out.scene->add_sphere(centre, radius, material, path);
    } else if (type == "mesh") {
      r.check_keys(s, path, {"type", "material", "file"});
      const std::string obj = resolve(base_dir, r.file_name(r.require(s, path, "file"), path + ".file"));
      TriangleMesh mesh = load_obj(obj, r, path + ".file");
      for (const Vec3& p : mesh.positions) r.check_point(p, path + ".file");
      try {
        out.scene->add_mesh(std::move(mesh), material, obj);
      } catch (const Error& err) {
        r.fail(path + ".file", err.what());
      }
    } else if (type == "triangles") {
      r.check_keys(s, path, {"type", "material", "vertices", "triangles"});
      TriangleMesh mesh;
      const json& v = r.require(s, path, "vertices");
      const json& t = r.require(s, path, "triangles");
      if (!v.is_array() || v.size() < 3) r.fail(path + ".vertices", "expected an array of [x, y, z] points");
      if (!t.is_array() || t.empty()) r.fail(path + ".triangles", "expected an array of [i, j, k] index triples");
      for (std::size_t k = 0; k < v.size(); ++k)
        mesh.positions.push_back(r.point(v[k], path + ".vertices[" + std::to_string(k) + "]"));
      for (std::size_t k = 0; k < t.size(); ++k) {
        const std::string tp = path + ".triangles[" + std::to_string(k) + "]";
        if (!t[k].is_array() || t[k].size() != 3) r.fail(tp, "expected [i, j, k]");
        mesh.triangles.push_back({r.integer(t[k][0], tp), r.integer(t[k][1], tp), r.integer(t[k][2], tp)});
      }
      try {
        out.scene->add_mesh(std::move(mesh), material, path);
      } catch (const Error& err) {
        std::string message = err.what();
        if (message.rfind(path + ": ", 0) == 0) message = message.substr(path.size() + 2);
        r.fail(path + ".triangles", message);
      }
    } else {
      r.fail(path + ".type", "unknown shape type '" + excerpt(type) + "' (valid: sphere, mesh, triangles)");
    }
  }
  out.scene->commit();
  std::string inside;
  if (out.scene->inside_geometry(out.camera.position(), &inside))
    r.fail("camera.position", "the camera is inside " + inside);

  // Environment (last: it is the slow part, and it is pointless when the rest is wrong)
  load_environment(r, r.require(root, "", "environment"), base_dir, options, out);
  return out;
}

LoadedScene load_scene_file(const std::string& path, const SceneLoadOptions& options) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (st.type() == std::filesystem::file_type::not_found) fail(path, "no such scene file");
  if (ec) fail(path, "cannot read the scene file: " + ec.message());
  require_regular_file(path);  // a FIFO or device would block or never end
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "cannot read the scene file: " + std::string(std::strerror(errno)));
  std::ostringstream text;
  text << in.rdbuf();
  return load_scene_text(text.str(), path, options);
}

std::unique_ptr<Material> load_material_text(const std::string& text, const std::string& source) {
  const LineTrackedJson doc = parse_json_with_lines(text, source);
  const Reader r(doc, source);
  return parse_material(r, doc.value, "material", std::filesystem::path(source).parent_path().string());
}

LoadedScene load_environment_text(const std::string& text, const std::string& source, const SceneLoadOptions& options) {
  const LineTrackedJson doc = parse_json_with_lines(text, source);
  const Reader r(doc, source);
  LoadedScene out;
  load_environment(r, doc.value, std::filesystem::path(source).parent_path().string(), options, out);
  return out;
}

const std::string& default_scene_json() {
  static const std::string text = R"json({
  "camera": {"position": [0.0, 1.6, -7.5], "look_at": [0.0, 0.55, 0.0], "up": [0, 1, 0], "fov": 32,
             "resolution": [480, 240]},
  "environment": {"probe": "default", "size": [1024, 512], "rotation": [180, 0, 0], "intensity": 1.0},
  "materials": {
    "ground":   {"type": "diffuse", "albedo": [0.45, 0.45, 0.42]},
    "matte":    {"type": "diffuse", "albedo": [0.75, 0.3, 0.2]},
    "rough001": {"type": "conductor", "roughness": 0.01},
    "rough005": {"type": "plastic", "diffuse": [0.1, 0.25, 0.6], "roughness": 0.05},
    "rough010": {"type": "conductor", "eta": [0.2, 0.92, 1.1], "k": [3.9, 2.45, 2.14], "roughness": 0.1},
    "rough030": {"type": "plastic", "diffuse": [0.2, 0.5, 0.15], "roughness": 0.3},
    "rough050": {"type": "conductor", "eta": [1.66, 0.88, 0.52], "k": [9.22, 6.27, 4.84], "roughness": 0.5}
  },
  "shapes": [
    {"type": "triangles", "material": "ground",
     "vertices": [[-500, 0, -500], [500, 0, -500], [500, 0, 500], [-500, 0, 500]],
     "triangles": [[0, 2, 1], [0, 3, 2]]},
    {"type": "sphere", "center": [ 3.2, 0.6, 0.0], "radius": 0.6, "material": "rough001"},
    {"type": "sphere", "center": [ 1.6, 0.6, 0.0], "radius": 0.6, "material": "rough005"},
    {"type": "sphere", "center": [ 0.0, 0.6, 0.0], "radius": 0.6, "material": "rough010"},
    {"type": "sphere", "center": [-1.6, 0.6, 0.0], "radius": 0.6, "material": "rough030"},
    {"type": "sphere", "center": [-3.2, 0.6, 0.0], "radius": 0.6, "material": "rough050"},
    {"type": "sphere", "center": [ 0.0, 0.9, 2.6], "radius": 0.9, "material": "matte"}
  ]
}
)json";
  return text;
}

void check_render_size(int width, int height) { check_request_size("a render", width, height, kRenderBytesPerPixel); }

LoadedScene make_default_scene(const SceneLoadOptions& options) {
  return load_scene_text(default_scene_json(), "<built-in default scene>", options);
}

}  // namespace envkit::render
