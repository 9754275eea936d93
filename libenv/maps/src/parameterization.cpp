#include <envkit/core/error.h>
#include <envkit/maps/parameterization.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>

namespace envkit {

std::string kind_name(Kind kind) {
  switch (kind) {
    case Kind::LatLong:
      return "latlong";
    case Kind::MirrorBall:
      return "mirrorball";
    case Kind::AngularMap:
      return "angular";
    case Kind::CubeMap:
      return "cube";
    case Kind::Octahedral:
      return "octahedral";
    case Kind::DualParaboloid:
      return "paraboloid";
    case Kind::HEALPix:
      return "healpix";
    case Kind::Perspective:
      return "perspective";
    case Kind::Fisheye:
      return "fisheye";
    case Kind::SkyLatLong:
      return "skylatlong";
    case Kind::SkyAngular:
      return "skyangular";
  }
  return "unknown";
}

Kind parse_kind(const std::string& name) {
  std::string n = name;
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (n == "latlong" || n == "latlon" || n == "equirect" || n == "equirectangular" || n == "spherical")
    return Kind::LatLong;
  if (n == "mirrorball" || n == "ball" || n == "chrome" || n == "mirror") return Kind::MirrorBall;
  if (n == "angular" || n == "angmap" || n == "lightprobe" || n == "probe") return Kind::AngularMap;
  if (n == "cube" || n == "cubemap") return Kind::CubeMap;
  if (n == "octahedral" || n == "octa" || n == "octahedron") return Kind::Octahedral;
  if (n == "paraboloid" || n == "dualparaboloid" || n == "dual-paraboloid") return Kind::DualParaboloid;
  if (n == "healpix" || n == "hpx") return Kind::HEALPix;
  if (n == "perspective" || n == "pinhole" || n == "rectilinear") return Kind::Perspective;
  if (n == "fisheye") return Kind::Fisheye;
  if (n == "skylatlong" || n == "sky-latlong") return Kind::SkyLatLong;
  if (n == "skyangular" || n == "sky-angular") return Kind::SkyAngular;
  std::string expected;
  for (std::size_t k = 0; k < kAllKinds.size(); ++k)
    expected += (k == 0 ? "" : k + 1 == kAllKinds.size() ? " or " : ", ") + kind_name(kAllKinds[k]);
  throw Error("unknown parameterization '" + name + "' (expected " + expected + ")");
}

bool Parameterization::same_grid(const Parameterization&) const { return false; }

bool Parameterization::clamp_tap(int& i, int& j) const {
  if (width_ <= 0 || height_ <= 0) return false;
  i = std::clamp(i, 0, width_ - 1);
  j = std::clamp(j, 0, height_ - 1);
  return true;
}

double Parameterization::solid_angle_density(Vec2 pos) const {
  const double h = 1e-3;
  return solid_angle(pos.x - h, pos.y - h, pos.x + h, pos.y + h) / (4.0 * h * h);
}

bool Parameterization::covered_point(int i, int j, Vec2& pos) const {
  Vec3 dir;
  pos = Vec2(i + 0.5, j + 0.5);
  if (to_direction(pos, dir)) return true;
  for (int n : {4, 16, 64})
    for (int b = 0; b < n; ++b)
      for (int a = 0; a < n; ++a) {
        pos = Vec2(i + (a + 0.5) / n, j + (b + 0.5) / n);
        if (to_direction(pos, dir)) return true;
      }
  return false;
}

bool Parameterization::resolve_tap(int /*anchor_i*/, int /*anchor_j*/, int& i, int& j) const { return clamp_tap(i, j); }

double Parameterization::texel_solid_angles(std::span<float> out) const {
  // Row sums in parallel, then a serial sum: the total does not depend on the thread count.
  const int W = width_, H = height_;
  std::vector<double> row_sums(H, 0.0);
  tbb::parallel_for(0, H, [&](int j) {
    double row = 0.0;
    for (int i = 0; i < W; ++i) {
      const double w = texel_solid_angle(i, j);
      out[static_cast<std::size_t>(j) * W + i] = static_cast<float>(w);
      row += w;
    }
    row_sums[j] = row;
  });
  double total = 0.0;
  for (double r : row_sums) total += r;
  return total;
}

}  // namespace envkit
