#include <envkit/cubemap.h>
#include <envkit/error.h>
#include <envkit/filter.h>
#include <envkit/octahedral.h>
#include <envkit/prefilter.h>
#include <envkit/solid_angle_table.h>
#include <envkit/texel_directions.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <functional>
#include <mutex>

namespace envkit {

std::string roughness_mapping_name(RoughnessMapping mapping) {
  switch (mapping) {
    case RoughnessMapping::Gltf:
      return "gltf";
    case RoughnessMapping::Filament:
      return "filament";
    case RoughnessMapping::Unreal:
      return "unreal";
  }
  return "gltf";
}

RoughnessMapping parse_roughness_mapping(const std::string& name) {
  if (name == "gltf" || name == "khronos") return RoughnessMapping::Gltf;
  if (name == "filament") return RoughnessMapping::Filament;
  if (name == "unreal" || name == "ue4" || name == "ue") return RoughnessMapping::Unreal;
  throw Error("unknown roughness mapping '" + name + "' (expected gltf, filament or unreal)");
}

double level_roughness(RoughnessMapping mapping, int level, int levels) {
  if (levels <= 1) return 0.0;
  const double lod = std::clamp(double(level) / (levels - 1), 0.0, 1.0);
  switch (mapping) {
    case RoughnessMapping::Gltf:
      return lod;
    case RoughnessMapping::Filament:
      return 1.0 - std::sqrt(1.0 - lod);
    case RoughnessMapping::Unreal: {
      const double level_from_1x1 = (levels - 1) - level;
      return std::min(1.0, std::exp2((1.0 - level_from_1x1) / 1.2));
    }
  }
  return lod;
}

double ggx_d(double n_dot_h, double alpha) {
  const double a2 = alpha * alpha;
  const double t = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
  return t > 0.0 ? a2 / (kPi * t * t) : 0.0;
}

std::unique_ptr<Parameterization> prefilter_level_param(Kind kind, int size, CubeBasis basis, TexelGrid grid) {
  if (kind == Kind::CubeMap) return std::make_unique<CubeMap>(size, CubeLayout::VerticalStrip, basis, grid);
  if (kind == Kind::Octahedral) return std::make_unique<OctahedralMap>(size);
  throw Error("prefilter: output must be a cube or an octahedral map, not " + kind_name(kind));
}

namespace {

// The split-sum weight D(n.h) (n.l) as a function of c = r.l (n = v = r, so
// (n.h)^2 = (1 + c) / 2), without the constant 1/pi, which the normalisation
// cancels.
inline double lobe_weight(double c, double a2) {
  if (c <= 0.0) return 0.0;
  const double t = 0.5 * (1.0 + c) * (a2 - 1.0) + 1.0;
  return c * a2 / (t * t);
}

// One texel of the summed cube pyramid: exact flux and solid angle of
// everything below it, and the centroids (unit directions) of its flux and of
// its solid angle.
struct Node {
  std::array<float, 4> flux;
  float omega;
  std::array<float, 3> flux_dir;  // unit centroids: finest nodes act as points there
  std::array<float, 3> omega_dir;
  std::array<float, 3> flux_mean;  // means of the unit directions below (length < 1)
  std::array<float, 3> omega_mean;
  // Central second moments E[(d - mean)(d - mean)^T] (xx, yy, zz, xy, xz, yz). Central, not E[d d^T]: the
  // variance of r . d is then r^T C r, where E[(r . d)^2] - (r . mean)^2 would cancel about 7 float digits away
  // and leave the sharp lobes' curvature term (w''/w ~ 1/alpha^4 near the peak) mostly rounding noise.
  std::array<float, 6> flux_cov;
  std::array<float, 6> omega_cov;
};

// The outer product d d^T in the order of Node's moments.
inline std::array<double, 6> outer(const Vec3& d) {
  return {d.x * d.x, d.y * d.y, d.z * d.z, d.x * d.y, d.x * d.z, d.y * d.z};
}

inline Vec3 to_vec(const std::array<float, 3>& v) { return Vec3(v[0], v[1], v[2]); }

// E[(d - mean)(d - mean)^T] from the weighted sum of d d^T, in double where the raw sums still hold the few
// digits that survive the subtraction (the finest level only); zero for an empty node.
inline std::array<float, 6> central_moments(const std::array<double, 6>& sum_dd, double weight, const Vec3& mean) {
  std::array<float, 6> c{};
  if (!(weight > 0.0)) return c;
  const std::array<double, 6> mm = outer(mean);
  for (int e = 0; e < 6; ++e) c[e] = float(sum_dd[e] / weight - mm[e]);
  for (int e = 0; e < 3; ++e) c[e] = std::max(c[e], 0.0f);  // variances, >= 0 but for rounding
  return c;
}

inline double quad_form(const std::array<float, 6>& m, double x, double y, double z) {
  return x * x * m[0] + y * y * m[1] + z * z * m[2] + 2.0 * (x * y * m[3] + x * z * m[4] + y * z * m[5]);
}

// d^2/dc^2 of lobe_weight (c > 0): with t = 1 + k (1 + c), k = (a^2 - 1) / 2, w = a^2 c / t^2.
inline double lobe_weight_curvature(double c, double a2) {
  if (c <= 0.0) return 0.0;
  const double k = 0.5 * (a2 - 1.0);
  const double t = 1.0 + k * (1.0 + c);
  const double t3 = t * t * t;
  return a2 * (-4.0 * k / t3 + 6.0 * c * k * k / (t3 * t));
}

class CubePyramid {
 public:
  // The finest level (a cube of face size 2^p, GL basis, world frame) gathers
  // the source texels whose centres it holds: their summed flux (L x exact
  // solid angle) and solid angle, and the flux- and solid-angle-weighted mean
  // of their directions. The pyramid is then a hierarchy over the source texels
  // themselves: summing every node at the finest level is the brute-force sum
  // with each group of source texels moved to its centroid, and a sun keeps its
  // direction at every level.
  CubePyramid(const MapRef& src, int face_size) : channels_(src.image.channels) {
    int p = 0;
    while ((1 << p) < face_size) ++p;
    levels_.resize(p + 1);
    radius_.resize(p + 1);
    for (int k = 0; k <= p; ++k) radius_[k] = std::atan(std::sqrt(2.0) / double(1 << k));
    const CubeMap cube(face_size, CubeLayout::VerticalStrip, CubeBasis::GL, TexelGrid::Centre);
    gather_source(cube, src, levels_[p]);
    for (int k = p - 1; k >= 0; --k) {
      const int s = 1 << k, s2 = 2 * s;
      const std::vector<Node>& fine = levels_[k + 1];
      std::vector<Node>& coarse = levels_[k];
      coarse.resize(std::size_t(6) * s * s);
      tbb::parallel_for(0, 6 * s, [&](int y) {
        const int f = y / s, j = y % s;
        for (int i = 0; i < s; ++i) {
          // Two passes over the four children: the means first, then the covariance about them by the
          // parallel-axis rule, C = sum w_i (C_i + (m_i - m)(m_i - m)^T) / sum w_i, which has no cancellation.
          std::array<const Node*, 4> child;
          std::array<double, 4> flux{}, w{};
          double om = 0.0, weight_sum = 0.0;
          Vec3 fd(0.0), od(0.0);
          for (int q = 0; q < 4; ++q) {
            const Node& c = *(child[q] = &fine[(std::size_t(f) * s2 + 2 * j + q / 2) * s2 + 2 * i + q % 2]);
            for (int ch = 0; ch < 4; ++ch) {
              flux[ch] += c.flux[ch];
              w[q] += std::abs(double(c.flux[ch]));
            }
            om += c.omega;
            weight_sum += w[q];
            fd += w[q] * to_vec(c.flux_mean);
            od += double(c.omega) * to_vec(c.omega_mean);
          }
          // Means of unit vectors, not re-normalised: r . mean is the exact mean of r . l over the texel, and with
          // the central moments the weight's second-order Taylor term is exact too.
          const double inv_o = om > 0.0 ? 1.0 / om : 0.0, inv_f = weight_sum > 0.0 ? 1.0 / weight_sum : 0.0;
          od *= inv_o;
          fd = weight_sum > 0.0 ? fd * inv_f : od;
          std::array<double, 6> fc{}, oc{};
          for (int q = 0; q < 4; ++q) {
            const Node& c = *child[q];
            const std::array<double, 6> sf = outer(to_vec(c.flux_mean) - fd), so = outer(to_vec(c.omega_mean) - od);
            for (int e = 0; e < 6; ++e) {
              fc[e] += w[q] * (c.flux_cov[e] + sf[e]);
              oc[e] += double(c.omega) * (c.omega_cov[e] + so[e]);
            }
          }
          Node& n = coarse[std::size_t(y) * s + i];
          for (int ch = 0; ch < 4; ++ch) n.flux[ch] = float(flux[ch]);
          n.omega = float(om);
          for (int e = 0; e < 6; ++e) {
            n.omega_cov[e] = float(oc[e] * inv_o);
            n.flux_cov[e] = weight_sum > 0.0 ? float(fc[e] * inv_f) : n.omega_cov[e];
          }
          n.flux_mean = n.flux_dir = {float(fd.x), float(fd.y), float(fd.z)};
          n.omega_mean = n.omega_dir = {float(od.x), float(od.y), float(od.z)};
        }
      });
    }
  }

  // The split-sum average around r for alpha > 0; out gets channels() values.
  void filter(const Vec3& r, double alpha, double accuracy, float* out) const {
    const double a2 = alpha * alpha;
    const int finest = int(levels_.size()) - 1;
    struct Item {
      int level;
      std::uint32_t index;
    };
    // Depth-first: at most 3 siblings wait per level, plus the six roots.
    std::array<Item, 6 + 3 * 32> stack;
    int top = 0;
    for (std::uint32_t f = 0; f < 6; ++f) stack[top++] = {0, f};
    std::array<double, 4> acc{};
    double weight = 0.0;
    const double rx = r.x, ry = r.y, rz = r.z;
    const double spread = 2.0 * alpha;
    const double horizon_rho = 0.25 * accuracy / alpha;
    // Per level: the distance refinement constant (refine_for_distance) and the horizon band half-width sin(2 rho).
    std::array<double, 32> reach{}, edge_of{};
    std::array<bool, 32> horizon_refine{};
    for (std::size_t k = 0; k < levels_.size(); ++k) {
      reach[k] = distance_reach(radius_[k], spread, accuracy);
      edge_of[k] = std::sin(std::min(2.0 * radius_[k], kPi / 2));
      horizon_refine[k] = radius_[k] > horizon_rho;
    }
    while (top > 0) {
      const Item it = stack[--top];
      const Node& n = levels_[it.level][it.index];
      const bool point = it.level == finest;
      const std::array<float, 3>& om = point ? n.omega_dir : n.omega_mean;
      const double co = rx * om[0] + ry * om[1] + rz * om[2];
      const double edge = edge_of[it.level];
      // Wholly below the horizon of r: every point of the texel lies within 2 rho of its centroid.
      if (co < -edge) continue;
      if (point) {
        const double cf = rx * n.flux_dir[0] + ry * n.flux_dir[1] + rz * n.flux_dir[2];
        const double wf = lobe_weight(cf, a2);
        for (int ch = 0; ch < channels_; ++ch) acc[ch] += wf * n.flux[ch];
        weight += lobe_weight(co, a2) * n.omega;
        continue;
      }
      // Texels across the horizon of r, where the weight has its kink, refine until small against the lobe.
      const bool straddles = co < edge;
      if (refine_for_distance(co, spread, reach[it.level]) || (straddles && horizon_refine[it.level])) {
        const int s = 1 << it.level, s2 = 2 * s;
        const std::uint32_t f = it.index / std::uint32_t(s * s);
        const std::uint32_t rem = it.index % std::uint32_t(s * s);
        const std::uint32_t j = rem / s, i = rem % s;
        for (std::uint32_t dj = 0; dj < 2; ++dj)
          for (std::uint32_t di = 0; di < 2; ++di)
            stack[top++] = {it.level + 1, (f * s2 + 2 * j + dj) * s2 + 2 * i + di};
        continue;
      }
      // Second-order quadrature over the texel: E[w(c)] ~ w(E c) + w''(E c) Var(c) / 2 (flux- or solid-angle
      // weighted), Var(c) = r^T C r; not across the horizon, where w has a kink.
      const double cf = rx * n.flux_mean[0] + ry * n.flux_mean[1] + rz * n.flux_mean[2];
      double wf = lobe_weight(cf, a2), wo = lobe_weight(co, a2);
      if (!straddles) {
        const double vf = std::max(0.0, quad_form(n.flux_cov, rx, ry, rz));
        const double vo = std::max(0.0, quad_form(n.omega_cov, rx, ry, rz));
        wf = std::max(0.0, wf + 0.5 * lobe_weight_curvature(cf, a2) * vf);
        wo = std::max(0.0, wo + 0.5 * lobe_weight_curvature(co, a2) * vo);
      }
      for (int ch = 0; ch < channels_; ++ch) acc[ch] += wf * n.flux[ch];
      weight += wo * n.omega;
    }
    for (int ch = 0; ch < channels_; ++ch) {
      const double v = weight > 0.0 ? acc[ch] / weight : 0.0;
      out[ch] = std::isfinite(v) ? float(v) : 0.0f;
    }
  }

 private:
  // A node of radius rho at chord distance d from r, t = d + spread, is refined while
  // rho > accuracy t (t / spread)^(1/6). Its second-order term errs by about (rho / t)^3 of its own weight, and the
  // nodes at distance ~t together hold a fraction ~(spread / t)^2 of the lobe's weight, so each ring's share of
  // the error still falls as (spread / t)^(3/2) while the node count per ring falls as (spread / t)^(1/3), instead
  // of staying constant down every level of the pyramid. The errors are systematic (they do not average out over
  // rings), so the exponent is small; larger ones: docs/PREFILTER.md.
  //
  // The per-level constant: (rho / accuracy)^6 spread, so that the test reads t^7 < reach.
  static double distance_reach(double rho, double spread, double accuracy) {
    const double q = rho / accuracy, q2 = q * q;
    return q2 * q2 * q2 * spread;
  }

  static bool refine_for_distance(double c, double spread, double reach) {
    const double t = std::sqrt(std::max(0.0, 2.0 - 2.0 * c)) + spread;
    const double t2 = t * t, t4 = t2 * t2;
    return t4 * t2 * t < reach;
  }

  void gather_source(const CubeMap& cube, const MapRef& src, std::vector<Node>& finest) const {
    const int w = src.image.width, h = src.image.height, channels = src.image.channels;
    const TexelDirections dirs(src.param);
    const SolidAngleTable omega(src.param);
    const TexelSource coverage(src.image, src.param);
    struct Acc {
      std::array<double, 4> flux{};
      double omega = 0.0, weight = 0.0;
      Vec3 flux_sum{0.0}, omega_sum{0.0};
      std::array<double, 6> flux_m2{}, omega_m2{};
    };
    // Source rows in fixed bands, each band gathering into its own run-length
    // list; bands merge in order, so the sums do not depend on the thread
    // count.
    // Chunks of bands at a time bound the memory of the lists (a 16k source makes tens of millions of runs).
    const int bands = std::min(h, 256), chunk = 16;
    std::vector<Acc> acc(std::size_t(cube.width()) * cube.height());
    std::vector<std::vector<std::pair<std::uint32_t, Acc>>> partial(bands);
    for (int b0 = 0; b0 < bands; b0 += chunk) {
      tbb::parallel_for(b0, std::min(bands, b0 + chunk), [&](int b) {
        const int y0 = int(std::int64_t(h) * b / bands), y1 = int(std::int64_t(h) * (b + 1) / bands);
        std::vector<std::pair<std::uint32_t, Acc>>& out = partial[b];
        std::uint32_t last = UINT32_MAX;
        for (int y = y0; y < y1; ++y)
          for (int x = 0; x < w; ++x) {
            const std::size_t index = std::size_t(y) * w + x;
            Vec3 d;
            if (!coverage.covered(index) || !dirs.centre(x, y, d)) continue;
            const double o = omega(x, y);
            if (!(o > 0.0)) continue;
            d = apply(src.to_world, d).normalized();
            const Vec2 pos = cube.to_image(d);
            const int i = std::clamp(int(pos.x), 0, cube.width() - 1), j = std::clamp(int(pos.y), 0, cube.height() - 1);
            const std::uint32_t t = std::uint32_t(j) * std::uint32_t(cube.width()) + std::uint32_t(i);
            if (t != last) {
              out.push_back({t, Acc{}});
              last = t;
            }
            Acc& a = out.back().second;
            const float* px = src.image.pixels.data() + index * channels;
            double lum = 0.0;
            for (int c = 0; c < channels; ++c) {
              a.flux[c] += double(px[c]) * o;
              if (c != src.image.alpha_channel) lum += std::abs(double(px[c]));
            }
            a.omega += o;
            a.omega_sum += o * d;
            a.weight += lum * o;
            a.flux_sum += (lum * o) * d;
            const std::array<double, 6> dd = {d.x * d.x, d.y * d.y, d.z * d.z, d.x * d.y, d.x * d.z, d.y * d.z};
            for (int q = 0; q < 6; ++q) {
              a.omega_m2[q] += o * dd[q];
              a.flux_m2[q] += lum * o * dd[q];
            }
          }
      });
      for (int b = b0; b < std::min(bands, b0 + chunk); ++b) {
        for (const auto& [t, a] : partial[b]) {
          Acc& to = acc[t];
          for (int c = 0; c < 4; ++c) to.flux[c] += a.flux[c];
          to.omega += a.omega;
          to.weight += a.weight;
          to.omega_sum += a.omega_sum;
          to.flux_sum += a.flux_sum;
          for (int q = 0; q < 6; ++q) {
            to.omega_m2[q] += a.omega_m2[q];
            to.flux_m2[q] += a.flux_m2[q];
          }
        }
        std::vector<std::pair<std::uint32_t, Acc>>().swap(partial[b]);
      }
    }
    finest.resize(acc.size());
    const TexelDirections centres(cube);
    tbb::parallel_for(0, cube.height(), [&](int y) {
      for (int x = 0; x < cube.width(); ++x) {
        const std::size_t t = std::size_t(y) * cube.width() + x;
        const Acc& a = acc[t];
        Node& n = finest[t];
        for (int c = 0; c < 4; ++c) n.flux[c] = float(a.flux[c]);
        n.omega = float(a.omega);
        // Finest nodes may be wider than the lobe: they act as points at their
        // (unit) centroids.
        Vec3 geometric;
        centres.centre(x, y, geometric);
        const Vec3 od = a.omega_sum.length() > 0.0 ? a.omega_sum.normalized() : geometric;
        const Vec3 fd = a.flux_sum.length() > 0.0 ? a.flux_sum.normalized() : od;
        n.flux_dir = {float(fd.x), float(fd.y), float(fd.z)};
        n.omega_dir = {float(od.x), float(od.y), float(od.z)};
        const Vec3 om = a.omega > 0.0 ? a.omega_sum / a.omega : od;
        const Vec3 fm = a.weight > 0.0 ? a.flux_sum / a.weight : om;
        n.omega_mean = {float(om.x), float(om.y), float(om.z)};
        n.flux_mean = {float(fm.x), float(fm.y), float(fm.z)};
        n.omega_cov = central_moments(a.omega_m2, a.omega, om);
        n.flux_cov = a.weight > 0.0 ? central_moments(a.flux_m2, a.weight, fm) : n.omega_cov;
      }
    });
  }

  int channels_;
  std::vector<std::vector<Node>> levels_;  // level k: 6 faces of 2^k x 2^k, index (face * s + j) * s + i
  std::vector<double> radius_;             // bound on the angular radius of a level-k texel
                                           // about its centre
};

// One output level: the split-sum average at every texel centre of `param` (map
// frame -> world by to_world).
Image convolve_level(const CubePyramid& pyramid, const Parameterization& param, const Mat3& to_world, const Image& like,
                     double alpha, double accuracy, const std::function<void(int)>& rows_done) {
  const TexelDirections dirs(param);
  Image out(param.width(), param.height(), like.channels);
  out.channel_names = like.channel_names;
  out.alpha_channel = like.alpha_channel;
  tbb::parallel_for(0, out.height, [&](int y) {
    for (int x = 0; x < out.width; ++x) {
      Vec3 d;
      float* px = out.at(x, y);
      if (!dirs.centre(x, y, d)) {
        std::fill(px, px + out.channels, 0.0f);
        continue;
      }
      pyramid.filter(apply(to_world, d).normalized(), alpha, accuracy, px);
    }
    if (rows_done) rows_done(out.width);
  });
  return out;
}

int power_of_two_at_least(int n) {
  int p = 1;
  while (p < n) p *= 2;
  return p;
}

int full_chain_levels(int size) {
  int levels = 1;
  while ((size >> levels) >= 1) ++levels;
  return levels;
}

}  // namespace

PrefilteredChain prefilter_ggx(const MapRef& src, const PrefilterOptions& options) {
  if (options.size < 1) throw Error("prefilter: size must be at least 1");
  if (!(options.accuracy > 0.0)) throw Error("prefilter: accuracy must be positive");
  if (src.image.channels > 4) throw Error("prefilter: at most 4 channels");
  const int max_levels = full_chain_levels(options.size);
  const int levels = options.levels == 0 ? max_levels : options.levels;
  if (levels < 1 || levels > max_levels)
    throw Error("prefilter: " + std::to_string(levels) + " levels requested; a size of " +
                std::to_string(options.size) + " has at most " + std::to_string(max_levels));
  int source_size = options.source_size;
  if (source_size == 0) {
    source_size = 1;
    while (source_size < options.size) source_size *= 2;
  }
  if (source_size < 1 || (source_size & (source_size - 1)) != 0)
    throw Error("prefilter: source size must be a power of two, not " + std::to_string(source_size));

  // Progress: the resampling passes take the first 30%, the levels the rest in
  // proportion to their texels.
  std::mutex progress_mutex;
  auto report = [&](double f) {
    if (!options.progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    options.progress(std::clamp(f, 0.0, 1.0));
  };

  PrefilteredChain chain;
  chain.mapping = options.mapping;
  chain.source_size = source_size;
  chain.cube_basis = options.cube_basis;
  chain.cube_grid = options.cube_grid;

  auto level0_param = prefilter_level_param(options.kind, options.size, options.cube_basis, options.cube_grid);
  const bool openexr_faces = options.kind == Kind::CubeMap && options.cube_basis == CubeBasis::Envkit &&
                             options.cube_grid == TexelGrid::Corner;
  ResampleOptions area;
  area.filter = Filter::Area;
  area.progress = [&](double f) { report(0.25 * f); };
  Image level0 = resample(src, *level0_param, options.to_world, area);

  const CubePyramid pyramid(src, source_size);
  report(0.3);

  auto make_level = [&](Image image, std::unique_ptr<Parameterization> param, int m) {
    EnvMap map;
    map.image = std::move(image);
    map.param = std::move(param);
    map.convention = openexr_faces ? "openexr" : "gl";
    map.rotation = options.to_world;
    const double r = level_roughness(options.mapping, m, levels);
    map.image.metadata["envkit:ibl_roughness_mapping"] = roughness_mapping_name(options.mapping);
    map.image.metadata["envkit:ibl_level"] = std::to_string(m);
    map.image.metadata["envkit:ibl_roughness"] = std::to_string(r);
    map.image.metadata["envkit:ibl_alpha"] = std::to_string(m == 0 ? 0.0 : r * r);
    chain.roughness.push_back(r);
    chain.alpha.push_back(m == 0 ? 0.0 : r * r);
    chain.levels.push_back(std::move(map));
  };
  make_level(std::move(level0), std::move(level0_param), 0);

  double total_texels = 0.0;
  for (int m = 1; m < levels; ++m) total_texels += double(std::max(1, options.size >> m)) * (options.size >> m);
  std::atomic<long long> done{0};
  for (int m = 1; m < levels; ++m) {
    const int n = std::max(1, options.size >> m);
    auto param = prefilter_level_param(options.kind, n, options.cube_basis, options.cube_grid);
    const double r = level_roughness(options.mapping, m, levels);
    const double alpha = std::max(r * r, 1e-4);
    const double per_texel = 1.0 / std::max(1.0, total_texels * (options.kind == Kind::CubeMap ? 6.0 : 1.0));
    Image out = convolve_level(pyramid, *param, options.to_world, chain.levels[0].image, alpha, options.accuracy,
                               [&](int texels) {
                                 const long long now = done.fetch_add(texels) + texels;
                                 report(0.3 + 0.7 * double(now) * per_texel);
                               });
    out.metadata = src.image.metadata;
    make_level(std::move(out), std::move(param), m);
  }
  report(1.0);
  return chain;
}

EnvMap irradiance_map(const MapRef& src, const IrradianceOptions& options) {
  if (options.size < 1) throw Error("irradiance: size must be at least 1");
  if (!(options.accuracy > 0.0)) throw Error("irradiance: accuracy must be positive");
  if (src.image.channels > 4) throw Error("irradiance: at most 4 channels");
  const int source_size =
      options.source_size == 0 ? power_of_two_at_least(std::max(options.size, 32)) : options.source_size;
  if ((source_size & (source_size - 1)) != 0)
    throw Error("irradiance: source size must be a power of two, not " + std::to_string(source_size));
  const CubePyramid pyramid(src, source_size);
  EnvMap map;
  map.param = prefilter_level_param(options.kind, options.size);
  map.convention = "gl";
  map.rotation = options.to_world;
  Image like(1, 1, src.image.channels);
  like.channel_names = src.image.channel_names;
  like.alpha_channel = src.image.alpha_channel;
  // With alpha = 1 the GGX weight D (n.l) is the clamped cosine / pi: the level
  // is E / pi.
  map.image = convolve_level(pyramid, *map.param, options.to_world, like, 1.0, options.accuracy, {});
  if (!options.divide_by_pi)
    for (int y = 0; y < map.image.height; ++y)
      for (int x = 0; x < map.image.width; ++x)
        for (int c = 0; c < map.image.channels; ++c)
          if (c != map.image.alpha_channel) map.image.at(x, y, c) *= float(kPi);
  map.image.metadata = src.image.metadata;
  map.image.metadata["envkit:ibl_irradiance"] = options.divide_by_pi ? "E/pi" : "E";
  return map;
}

GgxReference::GgxReference(const MapRef& src) : image_(src.image) {
  const TexelDirections dirs(src.param);
  const SolidAngleTable omega(src.param);
  const TexelSource source(src.image, src.param);
  dirs_.resize(src.image.texel_count());
  omega_.resize(src.image.texel_count());
  for (int y = 0; y < src.image.height; ++y)
    for (int x = 0; x < src.image.width; ++x) {
      const std::size_t i = std::size_t(y) * src.image.width + x;
      Vec3 d;
      if (!source.covered(i) || !dirs.centre(x, y, d)) continue;
      dirs_[i] = apply(src.to_world, d).normalized();
      omega_[i] = omega(x, y);
    }
}

void GgxReference::eval(const Vec3& r, double alpha, double* out) const {
  const int channels = image_.channels;
  std::vector<double> acc(channels, 0.0);
  double weight = 0.0;
  const double a2 = alpha * alpha;
  std::size_t nearest = 0;
  double best = -2.0;
  for (std::size_t i = 0; i < dirs_.size(); ++i) {
    if (omega_[i] <= 0.0) continue;
    const double c = r ^ dirs_[i];
    if (c > best) {
      best = c;
      nearest = i;
    }
    const double w = lobe_weight(c, a2) * omega_[i];
    if (w <= 0.0) continue;
    const float* px = image_.pixels.data() + i * channels;
    for (int ch = 0; ch < channels; ++ch) acc[ch] += w * px[ch];
    weight += w;
  }
  for (int ch = 0; ch < channels; ++ch) {
    const double v = alpha > 0.0 ? (weight > 0.0 ? acc[ch] / weight : 0.0) : image_.pixels[nearest * channels + ch];
    out[ch] = std::isfinite(v) ? v : 0.0;
  }
}

}  // namespace envkit
