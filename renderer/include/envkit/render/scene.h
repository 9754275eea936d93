#pragma once
/// @file scene.h
/// Geometry and materials of a scene, traced with Embree 3 (one device per Scene, rtcIntersect1/rtcOccluded1,
/// a fresh RTCIntersectContext per query). Shapes: triangle meshes and analytic spheres. Embree finds the hit in
/// float; sphere hits are then recomputed in double (exact point on the sphere, exact normal).
///
/// Surfaces are two-sided: Hit::geometric_normal is the outward normal of the shape (sphere: away from the
/// centre; triangle: (v1 - v0) x (v2 - v0), counter-clockwise winding seen from the front); the integrator flips it
/// to the side of the viewer.
#include <envkit/core/vec.h>
#include <envkit/render/camera.h>
#include <envkit/render/material.h>

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace envkit::render {

struct Hit {
  double t = 0;
  Vec3 position;
  Vec3 geometric_normal;  ///< unit, outward (see file comment)
  Vec3 shading_normal;    ///< unit, interpolated vertex normal (or the geometric normal), same side as geometric
  int material = -1;
  int shape = -1;  ///< index in shape order of insertion (spheres and meshes share one numbering)
};

struct TriangleMesh {
  std::vector<Vec3> positions;
  std::vector<std::array<int, 3>> triangles;
  std::vector<Vec3> normals;  ///< per vertex, empty = flat shading
};

class Scene {
 public:
  Scene();
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  /// Returns the material's index. Names must be unique (Error otherwise).
  int add_material(const std::string& name, std::unique_ptr<Material> material);
  /// Index of a material by name, -1 when unknown.
  int find_material(const std::string& name) const;
  std::vector<std::string> material_names() const;
  const Material& material(int index) const { return *materials_[static_cast<std::size_t>(index)]; }
  int material_count() const { return static_cast<int>(materials_.size()); }

  /// Adds a sphere; radius must be > 0 and finite (Error naming `label` otherwise).
  void add_sphere(const Vec3& centre, double radius, int material, const std::string& label = "sphere");
  /// Adds a mesh. Throws Error("<label>: N degenerate triangles (first: triangle k)") for zero-area or
  /// non-finite triangles, and for out-of-range indices.
  void add_mesh(TriangleMesh mesh, int material, const std::string& label = "mesh");
  /// Builds the BVH; call once after adding every shape, before tracing.
  void commit();

  /// Closest hit with t in (0, t_max). Thread-safe after commit().
  bool intersect(const Ray& ray, Hit& hit, double t_max = 1e300) const;
  /// Any hit with t in (0, t_max).
  bool occluded(const Ray& ray, double t_max = 1e300) const;
  /// True if p lies inside a sphere, or inside a closed mesh (every one of 6 probe rays first hits a mesh from
  /// behind). `which` receives the shape's label.
  bool inside_geometry(const Vec3& p, std::string* which = nullptr) const;

  /// Origin for a ray leaving `hit` towards the side of the geometric normal `side_normal` (already flipped to
  /// the outgoing side): offset by a small distance proportional to the position's magnitude.
  static Vec3 offset_origin(const Vec3& position, const Vec3& side_normal);

 private:
  struct Shape {
    bool is_sphere = false;
    Vec3 centre;
    double radius = 0;
    TriangleMesh mesh;
    int material = -1;
    std::string label;
  };
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<Shape> shapes_;
  std::vector<std::unique_ptr<Material>> materials_;
  std::vector<std::string> material_names_;
};

}  // namespace envkit::render
