#include <embree3/rtcore.h>
#include <envkit/core/error.h>
#include <envkit/render/scene.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace envkit::render {

struct Scene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
};

namespace {

void check_device(RTCDevice device, const char* what) {
  const RTCError err = rtcGetDeviceError(device);
  if (err != RTC_ERROR_NONE)
    throw Error(std::string("embree: ") + what + " failed (error " + std::to_string(err) + ")");
}

bool finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

RTCRayHit make_rayhit(const Ray& ray, double t_max) {
  RTCRayHit rh{};
  rh.ray.org_x = float(ray.origin.x);
  rh.ray.org_y = float(ray.origin.y);
  rh.ray.org_z = float(ray.origin.z);
  rh.ray.dir_x = float(ray.direction.x);
  rh.ray.dir_y = float(ray.direction.y);
  rh.ray.dir_z = float(ray.direction.z);
  rh.ray.tnear = 0.0f;
  rh.ray.tfar =
      t_max >= double(std::numeric_limits<float>::max()) ? std::numeric_limits<float>::infinity() : float(t_max);
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

}  // namespace

Scene::Scene() : impl_(std::make_unique<Impl>()) {
  impl_->device = rtcNewDevice(nullptr);
  if (!impl_->device)
    throw Error("embree: cannot create a device (error " + std::to_string(rtcGetDeviceError(nullptr)) + ")");
  impl_->scene = rtcNewScene(impl_->device);
  rtcSetSceneBuildQuality(impl_->scene, RTC_BUILD_QUALITY_HIGH);
  check_device(impl_->device, "rtcNewScene");
}

Scene::~Scene() = default;

int Scene::add_material(const std::string& name, std::unique_ptr<Material> material) {
  if (find_material(name) >= 0) throw Error("material '" + name + "' defined twice");
  materials_.push_back(std::move(material));
  material_names_.push_back(name);
  return int(materials_.size()) - 1;
}

int Scene::find_material(const std::string& name) const {
  for (std::size_t i = 0; i < material_names_.size(); ++i)
    if (material_names_[i] == name) return int(i);
  return -1;
}

std::vector<std::string> Scene::material_names() const { return material_names_; }

void Scene::add_sphere(const Vec3& centre, double radius, int material, const std::string& label) {
  if (!(radius > 0.0) || !std::isfinite(radius)) throw Error(label + ": radius must be positive and finite");
  if (!finite(centre)) throw Error(label + ": centre is not finite");
  if (material < 0 || material >= int(materials_.size())) throw Error(label + ": invalid material index");
  RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
  auto* v = static_cast<float*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), 1));
  v[0] = float(centre.x);
  v[1] = float(centre.y);
  v[2] = float(centre.z);
  // Slightly larger in float so that Embree never misses a ray the exact sphere catches; the exact double
  // intersection below decides.
  v[3] = float(radius) * (1.0f + 4e-7f);
  rtcCommitGeometry(geom);
  rtcAttachGeometryByID(impl_->scene, geom, unsigned(shapes_.size()));
  rtcReleaseGeometry(geom);
  check_device(impl_->device, "adding a sphere");
  Shape s;
  s.is_sphere = true;
  s.centre = centre;
  s.radius = radius;
  s.material = material;
  s.label = label;
  shapes_.push_back(std::move(s));
}

void Scene::add_mesh(TriangleMesh mesh, int material, const std::string& label) {
  if (material < 0 || material >= int(materials_.size())) throw Error(label + ": invalid material index");
  if (mesh.triangles.empty()) throw Error(label + ": mesh has no triangles");
  const int nv = int(mesh.positions.size());
  for (const Vec3& p : mesh.positions)
    if (!finite(p)) throw Error(label + ": non-finite vertex position");
  std::size_t degenerate = 0, first = 0;
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& tri = mesh.triangles[i];
    for (int k : tri)
      if (k < 0 || k >= nv)
        throw Error(label + ": triangle " + std::to_string(i) + " has an out-of-range vertex index");
    const Vec3 e1 = mesh.positions[tri[1]] - mesh.positions[tri[0]];
    const Vec3 e2 = mesh.positions[tri[2]] - mesh.positions[tri[0]];
    const double area2 = (e1 % e2).length();
    const double scale = std::max(e1.length2(), e2.length2());
    if (!(area2 > 1e-12 * scale) || !(scale > 0.0)) {
      if (degenerate++ == 0) first = i;
    }
  }
  if (degenerate > 0)
    throw Error(label + ": " + std::to_string(degenerate) + " degenerate triangle" + (degenerate > 1 ? "s" : "") +
                " (zero area; first: triangle " + std::to_string(first) + ")");
  if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
    throw Error(label + ": normal count differs from vertex count");
  for (Vec3& n : mesh.normals) {
    const double len = n.length();
    n = (len > 0.0 && std::isfinite(len)) ? n / len : Vec3(0, 0, 0);
  }

  RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                        3 * sizeof(float), mesh.positions.size()));
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    v[3 * i] = float(mesh.positions[i].x);
    v[3 * i + 1] = float(mesh.positions[i].y);
    v[3 * i + 2] = float(mesh.positions[i].z);
  }
  auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                             3 * sizeof(unsigned), mesh.triangles.size()));
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) idx[3 * i + k] = unsigned(mesh.triangles[i][k]);
  rtcCommitGeometry(geom);
  rtcAttachGeometryByID(impl_->scene, geom, unsigned(shapes_.size()));
  rtcReleaseGeometry(geom);
  check_device(impl_->device, "adding a mesh");
  Shape s;
  s.mesh = std::move(mesh);
  s.material = material;
  s.label = label;
  shapes_.push_back(std::move(s));
}

void Scene::commit() {
  rtcCommitScene(impl_->scene);
  check_device(impl_->device, "building the BVH");
}

Vec3 Scene::offset_origin(const Vec3& position, const Vec3& side_normal) {
  const double magnitude = std::max({std::abs(position.x), std::abs(position.y), std::abs(position.z), 1.0});
  return position + side_normal * (2e-5 * magnitude);
}

bool Scene::intersect(const Ray& ray, Hit& hit, double t_max) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh = make_rayhit(ray, t_max);
  rtcIntersect1(impl_->scene, &context, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  const Shape& shape = shapes_[rh.hit.geomID];
  hit.shape = int(rh.hit.geomID);
  hit.material = shape.material;
  if (shape.is_sphere) {
    // Exact ray-sphere intersection in double; take the root closest to Embree's float estimate.
    const Vec3 oc = ray.origin - shape.centre;
    const double b = oc ^ ray.direction;
    const Vec3 perp = oc - ray.direction * b;  // stable discriminant (Ray Tracing Gems ch. 7)
    const double disc = shape.radius * shape.radius - perp.length2();
    if (!(disc >= 0.0)) {
      // Embree's slightly larger sphere grazed it: treat as the tangent point.
      hit.t = -b;
    } else {
      const double s = std::sqrt(disc);
      const double q = -b - std::copysign(s, b);
      const double c = oc.length2() - shape.radius * shape.radius;
      double t0 = q, t1 = (q != 0.0) ? c / q : q;
      if (t0 > t1) std::swap(t0, t1);
      hit.t = std::abs(t0 - double(rh.ray.tfar)) <= std::abs(t1 - double(rh.ray.tfar)) ? t0 : t1;
      if (hit.t <= 0.0) hit.t = t1;
    }
    if (!(hit.t > 0.0) || hit.t >= t_max) return false;
    const Vec3 p = ray.origin + ray.direction * hit.t;
    Vec3 n = p - shape.centre;
    const double len = n.length();
    n = len > 0.0 ? n / len : Vec3(0, 1, 0);
    hit.position = shape.centre + n * shape.radius;
    hit.geometric_normal = n;
    hit.shading_normal = n;
    return true;
  }
  const auto& tri = shape.mesh.triangles[rh.hit.primID];
  const Vec3& p0 = shape.mesh.positions[tri[0]];
  const Vec3& p1 = shape.mesh.positions[tri[1]];
  const Vec3& p2 = shape.mesh.positions[tri[2]];
  const double u = rh.hit.u, v = rh.hit.v;
  hit.position = p0 * (1.0 - u - v) + p1 * u + p2 * v;
  hit.t = (hit.position - ray.origin) ^ ray.direction;
  if (!(hit.t > 0.0)) hit.t = double(rh.ray.tfar);
  hit.geometric_normal = ((p1 - p0) % (p2 - p0)).normalized();
  hit.shading_normal = hit.geometric_normal;
  if (!shape.mesh.normals.empty()) {
    Vec3 n =
        shape.mesh.normals[tri[0]] * (1.0 - u - v) + shape.mesh.normals[tri[1]] * u + shape.mesh.normals[tri[2]] * v;
    const double len = n.length();
    if (len > 1e-12) {
      n /= len;
      hit.shading_normal = (n ^ hit.geometric_normal) < 0.0 ? -n : n;
    }
  }
  return true;
}

bool Scene::occluded(const Ray& ray, double t_max) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh = make_rayhit(ray, t_max);
  rtcOccluded1(impl_->scene, &context, &rh.ray);
  return rh.ray.tfar < 0.0f;  // Embree sets tfar = -inf on a hit
}

bool Scene::inside_geometry(const Vec3& p, std::string* which) const {
  for (const Shape& s : shapes_)
    if (s.is_sphere && (p - s.centre).length() < s.radius) {
      if (which) *which = s.label;
      return true;
    }
  // Closed meshes: every probe ray (axes, slightly tilted to avoid edges) first hits a mesh from behind.
  static const Vec3 probes[6] = {Vec3(1, 0.0123, 0.0071),   Vec3(-1, 0.0093, -0.0137), Vec3(0.0111, 1, 0.0057),
                                 Vec3(-0.0077, -1, 0.0131), Vec3(0.0067, -0.0101, 1),  Vec3(0.0143, 0.0089, -1)};
  int behind = 0;
  int shape = -1;
  for (const Vec3& d : probes) {
    const Vec3 dir = d.normalized();
    Hit hit;
    Vec3 origin = p;
    bool found = false;
    for (int step = 0; step < 64 && intersect(Ray{origin, dir}, hit); ++step) {
      if (!shapes_[hit.shape].is_sphere) {
        found = true;
        break;
      }
      origin = hit.position + dir * (1e-6 * std::max(1.0, hit.position.length()));  // skip spheres
    }
    if (!found || (hit.geometric_normal ^ dir) <= 0.0) return false;
    ++behind;
    shape = hit.shape;
  }
  if (behind == 6 && which && shape >= 0) *which = shapes_[shape].label;
  return behind == 6;
}

}  // namespace envkit::render
