// Rasterization of a probe into any parameterization: each texel gets (1 / Omega) x integral of L over it.
//
// Pass 1 (parallel over rows): per texel, the background integral comes from the probe's exact lat-long
// rectangle integral when the target is a lat-long map, else from adaptive supersampling in image space
// (quadtree cells weighted by their exact solid angle, split where the cell is large, straddles a background
// discontinuity, or straddles a feature's boundary). The solid angle of each texel inside each feature is
// recorded sparsely.
// Pass 2 (serial, in row order): each feature's sampled solid angle is rescaled to its exact value, so the
// map's flux of every feature is exact even for a sun far smaller than a texel.
#include <envkit/core/error.h>
#include <envkit/core/vec.h>
#include <envkit/maps/latlong.h>
#include <envkit/probes.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>

namespace envkit::probes {

namespace {

constexpr std::size_t kMaxFeatures = 32;
using Mask = std::uint32_t;

// Which image channels receive colour, and the alpha channel.
struct ChannelMap {
  std::vector<int> colour;
  int alpha = -1;
  explicit ChannelMap(const Image& image) : alpha(image.alpha_channel) {
    for (int c = 0; c < image.channels; ++c)
      if (c != image.alpha_channel) colour.push_back(c);
  }
  void store(Image& image, int i, int j, const Vec3& rgb, bool covered) const {
    float* px = image.at(i, j);
    if (colour.size() == 1) {
      px[colour[0]] = static_cast<float>(0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z);
    } else {
      for (std::size_t c = 0; c < colour.size(); ++c)
        px[colour[c]] = c < 3 ? static_cast<float>(rgb[static_cast<int>(c)]) : 0.0f;
    }
    if (alpha >= 0) px[alpha] = covered ? 1.0f : 0.0f;
  }
  void add(Image& image, int i, int j, const Vec3& rgb) const {
    float* px = image.at(i, j);
    if (colour.size() == 1) {
      px[colour[0]] = static_cast<float>(px[colour[0]] + (0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z));
    } else {
      for (std::size_t c = 0; c < colour.size() && c < 3; ++c)
        px[colour[c]] = static_cast<float>(px[colour[c]] + rgb[static_cast<int>(c)]);
    }
  }
};

struct Context {
  const Probe& probe;
  const Parameterization& map;
  const RasterOptions& options;
  const std::vector<Feature>& features;
  bool rotate = false;                  // map_to_world is not the identity
  const LatLongMap* latlong = nullptr;  // set when exact lat-long integrals may be used
  Mask all_features = 0;

  bool direction(Vec2 pos, Vec3& dir) const {
    if (!map.to_direction(pos, dir)) return false;
    if (rotate) dir = apply(options.map_to_world, dir).normalized();
    return true;
  }
};

struct CellGeometry {
  bool has_centre = false;
  bool partial = false;  // some probed point of the cell has no data
  Vec3 centre;
  double radius = 0;  // angular radius bound around centre (rad)
};

// Centre direction and an angular radius bound from the corners, plus the edge midpoints for cells wider than
// a radian (for cells smaller than a hemisphere the farthest point of a cell bounded by parallels, meridians or
// great circles is one of these). Probe points sit a hair inside the cell so they never fall into the
// neighbouring texel or face.
CellGeometry cell_geometry(const Context& ctx, double x0, double y0, double x1, double y1) {
  CellGeometry g;
  const double xm = 0.5 * (x0 + x1), ym = 0.5 * (y0 + y1);
  g.has_centre = ctx.direction(Vec2(xm, ym), g.centre);
  const double ix = 1e-4 * (x1 - x0), iy = 1e-4 * (y1 - y0);
  const double xs[3] = {x0 + ix, xm, x1 - ix}, ys[3] = {y0 + iy, ym, y1 - iy};
  double max_chord2 = 0.0;
  auto probe = [&](int a, int b) {
    Vec3 d;
    if (!ctx.direction(Vec2(xs[a], ys[b]), d)) {
      g.partial = true;
      return;
    }
    if (g.has_centre) max_chord2 = std::max(max_chord2, (d - g.centre).length2());
  };
  probe(0, 0), probe(2, 0), probe(0, 2), probe(2, 2);
  constexpr double kWide = 0.9;  // chord^2 of about one radian
  if (!g.has_centre || g.partial || max_chord2 > kWide) probe(1, 0), probe(1, 2), probe(0, 1), probe(2, 1);
  if (!g.has_centre) {
    g.partial = true;
    g.radius = kPi;
    return g;
  }
  const double chord = std::min(2.0, std::sqrt(max_chord2));
  g.radius = std::min(kPi, 2.0 * std::asin(0.5 * chord) * 1.001);
  return g;
}

double angle_of_chord(const Vec3& a, const Vec3& b) { return 2.0 * std::asin(std::min(1.0, 0.5 * (a - b).length())); }

// Leaves that straddle a background discontinuity are sampled with a 16-point Hammersley set:
// x = (k + 1/2) / 16, y = bit-reversed k / 16 + 1/32.
constexpr int kEdgeSamples = 16;
double hammersley_y(int k) {
  const int r = ((k & 1) << 3) | ((k & 2) << 1) | ((k & 4) >> 1) | ((k & 8) >> 3);
  return (r + 0.5) / kEdgeSamples;
}

// Deterministic offsets in [0, 1/16)^2 from a leaf's position (splitmix64 of its corner's bits).
Vec2 leaf_shift(double x0, double y0) {
  std::uint64_t z = std::bit_cast<std::uint64_t>(x0) * 0x9E3779B97F4A7C15ull ^ std::bit_cast<std::uint64_t>(y0);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  constexpr double kUnit = 1.0 / 4294967296.0 / kEdgeSamples;
  return Vec2(static_cast<double>(z & 0xFFFFFFFFu) * kUnit, static_cast<double>(z >> 32) * kUnit);
}

// Whether rasterize() may use a probe's exact lat-long rectangle integrals on this map.
bool may_integrate_exactly(const Parameterization& map, const RasterOptions& options) {
  return options.exact_latlong && is_identity(options.map_to_world) && map.kind() == Kind::LatLong;
}

struct TexelSums {
  double weight = 0.0;
  Vec3 background{0.0, 0.0, 0.0};
  std::array<double, kMaxFeatures> feature{};
};

struct Refinement {
  bool background = true;  // sample the background (false when it is integrated exactly)
  bool smooth = true;      // the background varies smoothly (split down to smooth_radius)
  double edge_leaf = 0.0;  // leaf radius at background discontinuities for this texel
};

void integrate(const Context& ctx, const Refinement& ref, double x0, double y0, double x1, double y1,
               const CellGeometry& g, int depth, Mask mask, TexelSums& sums) {
  const double w = ctx.map.solid_angle(x0, y0, x1, y1);
  if (!(w > 0.0)) return;
  const RasterOptions& opt = ctx.options;
  bool refine = g.partial && depth < opt.max_partial_levels;

  // Features: drop those whose bounding cap misses the cell, note cells wholly inside a disk.
  Mask near = 0, inside = 0;
  if (g.has_centre) {
    for (Mask bits = mask; bits != 0; bits &= bits - 1) {
      const int k = std::countr_zero(bits);
      const Feature& f = ctx.features[static_cast<std::size_t>(k)];
      const double d = angle_of_chord(g.centre, f.centre);
      if (d - g.radius >= f.bound) continue;
      if (f.is_disk && d + g.radius < f.bound) {
        inside |= Mask{1} << k;
        continue;
      }
      near |= Mask{1} << k;
      if (g.radius > f.leaf_radius && depth < opt.max_feature_depth) refine = true;
    }
  } else {
    near = mask;
  }
  // A regular cell of angular radius r has about 2 r^2 sr: cells far smaller than that are slivers of a
  // singular rim, where refining would not pay.
  bool varies = false;
  if (ref.background && g.has_centre) {
    varies = ctx.probe.background_may_vary(g.centre, g.radius);
    if (ref.smooth && depth < opt.max_levels && g.radius > opt.smooth_radius &&
        w > 2.0 * opt.smooth_radius * opt.smooth_radius)
      refine = true;
    else if (varies && depth < opt.max_edge_levels && g.radius > ref.edge_leaf &&
             w > 2.0 * ref.edge_leaf * ref.edge_leaf)
      refine = true;
  }

  if (refine && depth < opt.max_feature_depth) {
    const double xm = 0.5 * (x0 + x1), ym = 0.5 * (y0 + y1);
    const double xs[3] = {x0, xm, x1}, ys[3] = {y0, ym, y1};
    // Split only for smoothness, with children (about half as wide) that will be plain leaves: sample their
    // centres directly instead of working out their geometry.
    if (ref.background && !g.partial && !varies && near == 0 && inside == 0 && 0.5 * g.radius <= opt.smooth_radius) {
      for (int b = 0; b < 2; ++b)
        for (int a = 0; a < 2; ++a) {
          const double cw = ctx.map.solid_angle(xs[a], ys[b], xs[a + 1], ys[b + 1]);
          Vec3 d;
          if (!(cw > 0.0) || !ctx.direction(Vec2(0.5 * (xs[a] + xs[a + 1]), 0.5 * (ys[b] + ys[b + 1])), d)) continue;
          sums.weight += cw;
          sums.background += ctx.probe.background(d) * cw;
        }
      return;
    }
    // Children test only the features whose boundary may cross this cell.
    const Mask child_mask = near;
    for (int b = 0; b < 2; ++b)
      for (int a = 0; a < 2; ++a) {
        const CellGeometry cg = cell_geometry(ctx, xs[a], ys[b], xs[a + 1], ys[b + 1]);
        const double before = sums.weight;
        integrate(ctx, ref, xs[a], ys[b], xs[a + 1], ys[b + 1], cg, depth + 1, child_mask, sums);
        // Features the whole cell lies in cover whatever solid angle the children kept.
        const double kept = sums.weight - before;
        for (Mask bits = inside; bits != 0; bits &= bits - 1) sums.feature[std::countr_zero(bits)] += kept;
      }
    return;
  }
  if (!g.has_centre) return;  // a sliver beyond a rim: no data at the deepest level
  double kept = w;
  if (varies) {
    // A leaf the background may change in: a Hammersley set resolves an edge 16 times finer along each image
    // axis than the centre alone would, without the bias an aligned grid has on axis-aligned edges (parallels
    // and meridians of a lat-long). Equal weights keep a constant exact.
    // Each leaf shifts the set by its own pseudo-random toroidal offset, so the leaves along an edge do not all
    // err the same way.
    Vec3 sum(0.0);
    int valid = 0;
    const Vec2 shift = leaf_shift(x0, y0);
    for (int k = 0; k < kEdgeSamples; ++k) {
      Vec3 d;
      double sx = (k + 0.5) / kEdgeSamples + shift.x, sy = hammersley_y(k) + shift.y;
      sx -= std::floor(sx), sy -= std::floor(sy);
      const Vec2 pos(x0 + (x1 - x0) * sx, y0 + (y1 - y0) * sy);
      if (!ctx.direction(pos, d)) continue;
      sum += ctx.probe.background(d);
      ++valid;
    }
    if (valid == 0) return;
    kept = w * valid / kEdgeSamples;
    sums.background += sum * (w / kEdgeSamples);
  } else if (ref.background) {
    sums.background += ctx.probe.background(g.centre) * w;
  }
  sums.weight += kept;
  for (Mask bits = inside; bits != 0; bits &= bits - 1) sums.feature[std::countr_zero(bits)] += kept;
  for (Mask bits = near; bits != 0; bits &= bits - 1) {
    const int k = std::countr_zero(bits);
    if (ctx.probe.in_feature(static_cast<std::size_t>(k), g.centre)) sums.feature[k] += kept;
  }
}

// Lat-long domain rectangle of texel (i, j), per latlong.h's grids. False if it does not reproduce the
// map's own texel solid angle (then the caller samples instead of trusting the closed form).
bool latlong_texel_rect(const LatLongMap& map, int i, int j, double omega, double r[4]) {
  const int w = map.width(), h = map.height();
  auto domain = [&](double p, int n) {
    if (map.grid() == TexelGrid::Centre || n == 1) return p / n;
    return std::clamp((p - 0.5) / (n - 1), 0.0, 1.0);
  };
  r[0] = domain(i, w), r[1] = domain(i + 1.0, w), r[2] = domain(j, h), r[3] = domain(j + 1.0, h);
  const double rect = latlong_rect_solid_angle(r[0], r[1], r[2], r[3]);
  return std::abs(rect - omega) <= 1e-9 * omega;
}

struct Hit {
  int i = 0;
  int k = 0;
  double fraction = 0.0;  // part of the texel's solid angle inside feature k
};

}  // namespace

void rasterize_into(const Probe& probe, const Parameterization& map, Image& image, const RasterOptions& options,
                    RasterStats* stats) {
  if (image.width != map.width() || image.height != map.height())
    throw Error("rasterize: image is " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                " but the map is " + std::to_string(map.width()) + "x" + std::to_string(map.height()));
  const std::vector<Feature>& features = probe.features();
  if (features.size() > kMaxFeatures) throw Error("rasterize: a probe may have at most 32 features");
  const ChannelMap channels(image);
  if (channels.colour.empty()) throw Error("rasterize: image has no colour channel");

  Context ctx{probe, map, options, features};
  ctx.rotate = !is_identity(options.map_to_world);
  if (may_integrate_exactly(map, options)) ctx.latlong = map.latlong_geometry();
  for (std::size_t k = 0; k < features.size(); ++k) ctx.all_features |= Mask{1} << k;

  const int width = map.width(), height = map.height();
  std::vector<std::vector<Hit>> hits(static_cast<std::size_t>(std::max(height, 0)));
  std::vector<double> omegas(static_cast<std::size_t>(std::max(width, 0)) * std::max(height, 0), 0.0);

  // On lat-long maps a feature can only touch the rows its polar-angle band crosses: other rows skip the
  // per-texel feature tests (and, with exact integrals, all sampling).
  auto row_features = [&](int j) {
    if (!ctx.latlong) return ctx.all_features;
    double rect[4];
    latlong_texel_rect(*ctx.latlong, 0, j, 0.0, rect);
    Mask mask = 0;
    for (std::size_t k = 0; k < features.size(); ++k) {
      const double theta = safe_acos(features[k].centre.y);
      const double margin = 1e-9 + features[k].bound;
      if (theta + margin >= LatLongMap::polar_angle(rect[2]) && theta - margin <= LatLongMap::polar_angle(rect[3]))
        mask |= Mask{1} << k;
    }
    return mask;
  };

  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
    for (int j = rows.begin(); j < rows.end(); ++j) {
      const Mask row_mask = row_features(j);
      for (int i = 0; i < width; ++i) {
        const double omega = map.texel_solid_angle(i, j);
        omegas[static_cast<std::size_t>(j) * width + i] = omega;
        if (!(omega > 0.0)) {
          channels.store(image, i, j, Vec3(0.0), false);
          continue;
        }
        Refinement ref;
        double rect[4];
        Vec3 exact_integral;
        const bool exact = ctx.latlong && latlong_texel_rect(*ctx.latlong, i, j, omega, rect) &&
                           probe.integrate_latlong(rect[0], rect[1], rect[2], rect[3], exact_integral);
        // A uniform background needs no sampling: only the features do.
        const bool uniform = !exact && probe.background_variation() == Probe::Variation::Uniform;
        ref.background = !exact && !uniform;
        ref.smooth = probe.background_variation() == Probe::Variation::Smooth;
        TexelSums sums;
        if (ref.background || row_mask != 0) {
          const CellGeometry g = cell_geometry(ctx, i, j, i + 1.0, j + 1.0);
          ref.edge_leaf = std::min(std::ldexp(g.radius, -options.edge_levels), options.edge_radius);
          integrate(ctx, ref, i, j, i + 1.0, j + 1.0, g, 0, row_mask, sums);
        }
        // Normalise by the weight actually integrated: a constant comes out exactly, and slivers without
        // data (a texel cut by a rim) do not darken the texel.
        const double weight = exact     ? latlong_rect_solid_angle(rect[0], rect[1], rect[2], rect[3])
                              : uniform ? (sums.weight > 0.0 ? sums.weight : omega)
                                        : sums.weight;
        if (!(weight > 0.0)) {
          channels.store(image, i, j, Vec3(0.0), true);
          continue;
        }
        const Vec3 average = exact     ? exact_integral / weight
                             : uniform ? probe.background(Vec3(0, 1, 0))
                                       : sums.background / weight;
        channels.store(image, i, j, average, true);
        for (std::size_t k = 0; k < features.size(); ++k)
          if (sums.feature[k] > 0.0)
            hits[static_cast<std::size_t>(j)].push_back(Hit{i, static_cast<int>(k), sums.feature[k] / weight});
      }
    }
  });

  // Pass 2: rescale each feature's sampled solid angle to the exact one.
  std::vector<FeatureStats> fstats(features.size());
  std::vector<double> sampled(features.size(), 0.0);
  for (int j = 0; j < height; ++j)
    for (const Hit& h : hits[static_cast<std::size_t>(j)])
      sampled[static_cast<std::size_t>(h.k)] += h.fraction * omegas[static_cast<std::size_t>(j) * width + h.i];
  for (std::size_t k = 0; k < features.size(); ++k) {
    FeatureStats& s = fstats[k];
    s.target = features[k].solid_angle;
    s.sampled = sampled[k];
    if (sampled[k] > 0.0) {
      s.scale = s.target / sampled[k];
      continue;
    }
    // Missed by every subsample: the whole flux goes to the texel that sees the feature's centre.
    s.missed = true;
    s.scale = 0.0;
    const Vec3 local = ctx.rotate ? apply(transposed(options.map_to_world), features[k].centre) : features[k].centre;
    const Vec2 p = map.to_image(local);
    const int ti = static_cast<int>(std::floor(p.x)), tj = static_cast<int>(std::floor(p.y));
    const double omega =
        (ti >= 0 && tj >= 0 && ti < width && tj < height) ? omegas[static_cast<std::size_t>(tj) * width + ti] : 0.0;
    if (omega > 0.0)
      channels.add(image, ti, tj, features[k].excess * (s.target / omega));
    else
      s.lost = true;
  }
  for (int j = 0; j < height; ++j)
    for (const Hit& h : hits[static_cast<std::size_t>(j)]) {
      const FeatureStats& s = fstats[static_cast<std::size_t>(h.k)];
      if (!s.missed)
        channels.add(image, h.i, j, features[static_cast<std::size_t>(h.k)].excess * (s.scale * h.fraction));
    }
  if (stats) stats->features = std::move(fstats);
}

Image rasterize(const Probe& probe, const Parameterization& map, const RasterOptions& options, RasterStats* stats) {
  Image image(map.width(), map.height(), options.alpha ? 4 : 3);
  rasterize_into(probe, map, image, options, stats);
  return image;
}

double edge_evaluations(const Probe& probe, const Parameterization& map, const RasterOptions& options) {
  const double length = probe.discontinuity_length();
  const double texels = double(map.width()) * double(map.height());
  // Whether the probe has lat-long integrals, asked of an empty rectangle (the whole sphere would cost a checker
  // one integral per cell).
  Vec3 unused;
  if (!(length > 0.0) || !(texels > 0.0) ||
      (may_integrate_exactly(map, options) && probe.integrate_latlong(0.0, 0.0, 0.0, 0.0, unused)))
    return 0.0;
  // A texel of the mean solid angle 4 pi / texels, as a square, has the half-diagonal sqrt(2 pi / texels);
  // rasterize() refines it down to leaves of edge_leaf's radius where the background may vary.
  const double texel_radius = std::sqrt(kTwoPi / texels);
  const double leaf_radius = std::min(std::ldexp(texel_radius, -options.edge_levels), options.edge_radius);
  // A curve crosses about length / (2 r) leaves of radius r, the caps of as many again reach it, and cells halve
  // down to a radius below r: about 2 length / r leaves (measured against rasterize()'s calls in the tests),
  // at most every texel split down to leaves, about 2 (texel radius / r)^2 each.
  const double ratio = texel_radius / leaf_radius;
  const double leaves = 2.0 * std::min(length / leaf_radius, texels * ratio * ratio);
  return kEdgeSamples * leaves;
}

Vec3 image_power(const Image& image, const Parameterization& map) {
  if (image.width != map.width() || image.height != map.height())
    throw Error("image_power: image size does not match the map");
  const ChannelMap channels(image);
  if (channels.colour.empty()) return Vec3(0.0);
  std::vector<Vec3> rows(static_cast<std::size_t>(std::max(image.height, 0)), Vec3(0.0));
  tbb::parallel_for(tbb::blocked_range<int>(0, image.height), [&](const tbb::blocked_range<int>& range) {
    for (int j = range.begin(); j < range.end(); ++j) {
      Vec3 sum(0.0);
      for (int i = 0; i < image.width; ++i) {
        const double omega = map.texel_solid_angle(i, j);
        if (!(omega > 0.0)) continue;
        const float* px = image.at(i, j);
        if (channels.colour.size() == 1) {
          sum += Vec3(px[channels.colour[0]]) * omega;
        } else {
          for (std::size_t c = 0; c < 3 && c < channels.colour.size(); ++c)
            sum[static_cast<int>(c)] += static_cast<double>(px[channels.colour[c]]) * omega;
        }
      }
      rows[static_cast<std::size_t>(j)] = sum;
    }
  });
  Vec3 total(0.0);
  for (const Vec3& r : rows) total += r;
  return total;
}

}  // namespace envkit::probes
