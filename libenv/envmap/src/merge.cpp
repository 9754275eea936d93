#include <envkit/core/error.h>
#include <envkit/envmap/merge.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/resample/filter.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>

namespace envkit {

namespace {

/// Where a capture holds data, seen from the world: the resampler's rule (the
/// direction's image position lies inside the image) and, for maps with blank
/// texels (outside a disk, the cells of a cross), a position that holds data.
class Footprint {
 public:
  explicit Footprint(const EnvMap& map)
      : param_(*map.param), to_world_(map.to_world()), to_map_(transposed(map.to_world())) {}

  bool sees(const Vec3& world_dir) const {
    const Vec2 p = param_.to_image(apply(to_map_, world_dir));
    if (!(p.x >= 0.0 && p.y >= 0.0 && p.x <= param_.width() && p.y <= param_.height())) return false;
    Vec3 d;
    return !param_.has_blank_texels() || param_.to_direction(p, d);
  }

  /// True when every direction is seen: no coverage to compute.
  bool whole_sphere() const { return param_.covers_sphere() && !param_.has_blank_texels(); }

  /// World directions the footprint's edge may turn sharply at (the image's
  /// corners, a camera view's vertices) and one inside it (the image centre):
  /// an output texel holding one is integrated finely however small the
  /// capture or its corner is there.
  std::vector<Vec3> landmarks() const {
    const double w = param_.width(), h = param_.height(), e = 1e-7;
    std::vector<Vec3> out;
    for (const Vec2& p : {Vec2(e, e), Vec2(w - e, e), Vec2(e, h - e), Vec2(w - e, h - e), Vec2(0.5 * w, 0.5 * h)}) {
      Vec3 d;
      if (param_.to_direction(p, d)) out.push_back(apply(to_world_, d));
    }
    return out;
  }

 private:
  const Parameterization& param_;
  Mat3 to_world_, to_map_;
};

using SeesFn = std::function<bool(const Vec3&)>;

/// Exact covered fractions by adaptive quadrature: a texel is cut into
/// quadrants, each cell's corners and centre tested; a cell whose points agree
/// counts as covered or uncovered whole (below the first two levels), the
/// others are cut again down to kMaxDepth (1/256 of a texel on a side), where
/// a cell counts in proportion to its points. Cells are weighted by their
/// solid angle; points shared by neighbouring cells are tested once.
class CoverageIntegrator {
 public:
  CoverageIntegrator(const Parameterization& dst, const Mat3& dst_to_world, SeesFn sees)
      : dst_(dst), dst_to_world_(dst_to_world), sees_(std::move(sees)) {}

  /// Covered, uncovered or neither (no data in the output) at position q.
  enum State : unsigned { None = 0, In = 1, Out = 2 };
  State state(Vec2 q) const {
    Vec3 d;
    if (!dst_.to_direction(q, d)) return None;
    return sees_(apply(dst_to_world_, d)) ? In : Out;
  }

  /// Union of the states of texel (i, j)'s 3 x 3 sample points (corners just
  /// inside it, so they belong to its own face).
  unsigned texel_states(int i, int j) const {
    unsigned states = 0;
    for (const double b : {kInset, 0.5, 1.0 - kInset})
      for (const double a : {kInset, 0.5, 1.0 - kInset}) states |= state(Vec2(i + a, j + b));
    return states;
  }

  /// Covered fraction of texel (i, j) and, when it is not 0, a position in the
  /// texel that the capture sees.
  double fraction(int i, int j, Vec2* seen_at = nullptr) const {
    Sums s;
    Cell cell{i, j, double(i), double(j), 1.0, {}};
    for (int k = 0; k < 4; ++k) cell.corner[k] = probe(cell.corner_position(k), s);
    refine(cell, 0, s);
    if (seen_at && s.found) *seen_at = s.seen_at;
    if (!(s.all > 0.0))  // no solid angle to weigh by: count points
      return s.points_all > 0 ? double(s.points_in) / double(s.points_all) : 0.0;
    return s.in == s.all ? 1.0 : s.in / s.all;
  }

 private:
  static constexpr int kMinDepth = 2, kMaxDepth = 8;
  static constexpr double kInset = 1e-7;

  struct Sums {
    double in = 0.0, all = 0.0;
    long points_in = 0, points_all = 0;
    bool found = false;
    Vec2 seen_at;
  };

  /// A square [x0, x0 + side]^2 inside texel (i, j), with the states of its
  /// corners (top left, top right, bottom left, bottom right).
  struct Cell {
    int i, j;
    double x0, y0, side;
    State corner[4];
    /// A point of the cell, kept just inside the texel.
    Vec2 at(double x, double y) const {
      return Vec2(std::clamp(x, i + kInset, i + 1.0 - kInset), std::clamp(y, j + kInset, j + 1.0 - kInset));
    }
    Vec2 corner_position(int k) const { return at(x0 + (k & 1) * side, y0 + (k >> 1) * side); }
  };

  /// The state at p, remembering the first covered point.
  State probe(Vec2 p, Sums& s) const {
    const State st = state(p);
    if (st == In && !s.found) {
      s.found = true;
      s.seen_at = p;
    }
    return st;
  }

  void refine(const Cell& cell, int depth, Sums& s) const {
    const double h = 0.5 * cell.side;
    const Vec2 centre(cell.x0 + h, cell.y0 + h);
    const State mid = probe(centre, s);
    int in = mid == In, out = mid == Out;
    for (const State st : cell.corner) in += st == In, out += st == Out;
    const bool uniform = in == 0 || out == 0;
    if (depth >= kMaxDepth || (uniform && depth >= kMinDepth)) {
      const double w = dst_.solid_angle_density(centre) * cell.side * cell.side;
      s.all += w;
      s.in += out == 0 ? (in > 0 ? w : 0.0) : w * double(in) / double(in + out);
      s.points_in += in;
      s.points_all += in + out;
      return;
    }
    const State top = probe(cell.at(cell.x0 + h, cell.y0), s);
    const State left = probe(cell.at(cell.x0, cell.y0 + h), s);
    const State right = probe(cell.at(cell.x0 + cell.side, cell.y0 + h), s);
    const State bottom = probe(cell.at(cell.x0 + h, cell.y0 + cell.side), s);
    const State(&c)[4] = cell.corner;
    const State children[4][4] = {
        {c[0], top, left, mid}, {top, c[1], mid, right}, {left, mid, c[2], bottom}, {mid, right, bottom, c[3]}};
    for (int k = 0; k < 4; ++k) {
      Cell child{cell.i, cell.j, cell.x0 + (k & 1) * h, cell.y0 + (k >> 1) * h, h, {}};
      std::copy(children[k], children[k] + 4, child.corner);
      refine(child, depth + 1, s);
    }
  }

  const Parameterization& dst_;
  Mat3 dst_to_world_;
  SeesFn sees_;
};

/// Fraction of each output texel's solid angle (row-major) in which `sees`
/// holds; exactly 1 on texels wholly seen, 0 on texels without data.
std::vector<double> coverage_fractions(const Parameterization& dst, const Mat3& dst_to_world, SeesFn sees,
                                       const std::vector<Vec3>& landmarks) {
  const int W = dst.width(), H = dst.height();
  const CoverageIntegrator integrator(dst, dst_to_world, std::move(sees));
  // The state of each texel's centre. A footprint's edge that crosses a texel
  // separates the centres of the 3 x 3 texels around it (they surround it), so
  // only texels whose centre differs from a neighbour's can be cut; where the
  // neighbours are not all on the texel's own chart (image borders, cube face
  // edges) or hold no data, the texel's own 3 x 3 points are tested too.
  std::vector<unsigned> centre(std::size_t(W) * H);
  tbb::parallel_for(0, H, [&](int j) {
    for (int i = 0; i < W; ++i) centre[std::size_t(j) * W + i] = integrator.state(Vec2(i + 0.5, j + 0.5));
  });
  std::vector<unsigned char> fine(centre.size(), 0);
  tbb::parallel_for(0, H, [&](int j) {
    for (int i = 0; i < W; ++i) {
      const unsigned st = centre[std::size_t(j) * W + i];
      const Parameterization::TapBlock block = dst.tap_block(i, j);
      bool differs = false, own_chart = true;
      for (int b = j - 1; b <= j + 1; ++b)
        for (int a = i - 1; a <= i + 1; ++a) {
          if (!block.holds(a, b)) {
            own_chart = false;
            continue;
          }
          const unsigned n = centre[std::size_t(b) * W + a];
          if (n == CoverageIntegrator::None) own_chart = false;
          differs = differs || (n != CoverageIntegrator::None && n != st);
        }
      const unsigned points = own_chart ? st : integrator.texel_states(i, j);
      fine[std::size_t(j) * W + i] = differs || (points & 3u) == 3u || (points != 0u && st == 0u);
    }
  });
  // A landmark (a corner of a camera view, a small capture) may lie inside one
  // texel between every centre.
  const Mat3 world_to_dst = transposed(dst_to_world);
  for (const Vec3& d : landmarks) {
    const Vec2 q = dst.to_image(apply(world_to_dst, d));
    if (!(q.x >= 0.0 && q.y >= 0.0 && q.x <= W && q.y <= H)) continue;
    const int i = std::clamp(int(q.x), 0, W - 1), j = std::clamp(int(q.y), 0, H - 1);
    fine[std::size_t(j) * W + i] = 1;
  }
  std::vector<double> coverage(centre.size(), 0.0);
  tbb::parallel_for(0, H, [&](int j) {
    for (int i = 0; i < W; ++i) {
      const std::size_t t = std::size_t(j) * W + i;
      coverage[t] = fine[t] ? integrator.fraction(i, j) : (centre[t] == CoverageIntegrator::In);
    }
  });
  return coverage;
}

/// 1 on every output texel that holds data (a capture that sees the sphere).
std::vector<double> whole_coverage(const Parameterization& dst) {
  const TexelDirections dirs(dst);
  const int W = dst.width(), H = dst.height();
  std::vector<double> coverage(std::size_t(W) * H, 0.0);
  tbb::parallel_for(0, H, [&](int j) {
    for (int i = 0; i < W; ++i) {
      Vec3 d;
      Vec2 q;
      coverage[std::size_t(j) * W + i] = dirs.centre(i, j, d) || dst.covered_point(i, j, q) ? 1.0 : 0.0;
    }
  });
  return coverage;
}

/// The capture's colour channels: 1 or 3 of them (a grey capture's one is
/// read as R, G and B).
std::vector<int> colour_channels(const Capture& c) {
  const Image& img = c.map.image;
  std::vector<int> colour;
  for (int ch = 0; ch < img.channels; ++ch)
    if (ch != img.alpha_channel) colour.push_back(ch);
  if (colour.size() == 2 || colour.empty())
    throw Error(c.name + ": a capture needs 1 or at least 3 colour channels, not " + std::to_string(colour.size()));
  if (colour.size() > 3) colour.resize(3);
  return colour;
}

/// The mask of each capture texel: the capture's mask times its own alpha,
/// clamped to [0, 1]. Empty when both are absent.
Image mask_of(const Capture& c) {
  const Image& img = c.map.image;
  if (c.mask && (c.mask->width != img.width || c.mask->height != img.height))
    throw Error(c.name + ": mask is " + std::to_string(c.mask->width) + "x" + std::to_string(c.mask->height) +
                " but the capture is " + std::to_string(img.width) + "x" + std::to_string(img.height));
  if (!c.mask && img.alpha_channel < 0) return {};
  Image m(img.width, img.height, 1);
  m.channel_names = {"M"};
  bool all_ones = true;
  for (int j = 0; j < img.height; ++j)
    for (int i = 0; i < img.width; ++i) {
      double v = c.mask ? std::clamp(double(c.mask->at(i, j, 0)), 0.0, 1.0) : 1.0;
      if (img.alpha_channel >= 0) v *= std::clamp(double(img.at(i, j, img.alpha_channel)), 0.0, 1.0);
      if (!(v >= 0.0)) v = 0.0;  // NaN
      m.at(i, j, 0) = float(v);
      all_ones = all_ones && v == 1.0;
    }
  return all_ones ? Image{} : m;  // a mask that keeps everything is no mask
}

/// The capture's colour (1 or 3 channels, no alpha) multiplied by its mask.
Image masked_colour(const Capture& c, const std::vector<int>& colour, const Image& mask) {
  const Image& img = c.map.image;
  Image out(img.width, img.height, int(colour.size()));
  out.channel_names.clear();
  for (int ch : colour) out.channel_names.push_back(ch < int(img.channel_names.size()) ? img.channel_names[ch] : "Y");
  out.alpha_channel = -1;
  out.metadata = img.metadata;
  tbb::parallel_for(0, img.height, [&](int j) {
    for (int i = 0; i < img.width; ++i) {
      const float m = mask.empty() ? 1.0f : mask.at(i, j, 0);
      for (std::size_t k = 0; k < colour.size(); ++k) out.at(i, j, int(k)) = img.at(i, j, colour[k]) * m;
    }
  });
  return out;
}

/// One capture, as it reaches the output grid.
struct Layer {
  Image source_colour;           ///< the capture's colour x mask, on its own grid
  Image source_mask;             ///< its mask on its own grid; empty when it has none
  Image colour;                  ///< mean of colour x mask over the part of each output texel
                                 ///< the capture sees (the resampler's coverage after it)
  Image mask;                    ///< mean of the mask there; empty when the capture has none
  std::vector<double> coverage;  ///< exact covered fraction of each texel
};

Layer layer_of(const Capture& c, const Footprint& footprint, const Parameterization& dst, const Mat3& dst_to_world,
               const ResampleOptions& options) {
  Layer layer;
  layer.source_mask = mask_of(c);
  layer.source_colour = masked_colour(c, colour_channels(c), layer.source_mask);
  // The colour through the area resampler as envconvert resamples it (flux
  // conserving, the sun splatted exactly); the mask's mean through the same
  // resampler without the exact splat (a mask holds no sun, and a constant
  // mask must stay exactly constant).
  layer.colour = resample({layer.source_colour, *c.map.param, c.map.to_world()}, dst, dst_to_world, options);
  if (!layer.source_mask.empty()) {
    ResampleOptions plain = options;
    plain.hot_contrast = std::numeric_limits<double>::infinity();
    layer.mask = resample({layer.source_mask, *c.map.param, c.map.to_world()}, dst, dst_to_world, plain);
  }
  layer.coverage =
      footprint.whole_sphere()
          ? whole_coverage(dst)
          : coverage_fractions(
                dst, dst_to_world, [&footprint](const Vec3& d) { return footprint.sees(d); }, footprint.landmarks());
  return layer;
}

/// Reads a capture where an output position looks, for a texel it sees too
/// thinly for the area resampler's sub-samples to reach: its colour (x mask)
/// and mask, bilinear. The texel sources are built on first use (rare).
class SliverReader {
 public:
  SliverReader(const Capture& c, const Layer& layer, const Parameterization& dst, const Mat3& dst_to_world)
      : capture_(c), layer_(layer), dst_(dst), dst_to_src_(compose(transposed(c.map.to_world()), dst_to_world)) {}

  bool read(Vec2 q, double rgb[3], double& m) {
    // Isolated: while this thread waits for the nested parallel work, it must not
    // take another texel of the caller's loop and reach this call_once again.
    std::call_once(once_, [this] {
      tbb::this_task_arena::isolate([this] {
        colour_.emplace(layer_.source_colour, *capture_.map.param);
        if (!layer_.source_mask.empty()) mask_.emplace(layer_.source_mask, *capture_.map.param);
      });
    });
    Vec3 d;
    if (!dst_.to_direction(q, d)) return false;
    const Vec2 p = capture_.map.param->to_image(apply(dst_to_src_, d));
    float value[3] = {0, 0, 0};
    if (!colour_->sample(p, Filter::Bilinear, value)) return false;
    for (int k = 0; k < 3; ++k) rgb[k] = value[layer_.source_colour.channels == 1 ? 0 : k];
    float mv = 1.0f;
    if (mask_ && !mask_->sample(p, Filter::Bilinear, &mv)) return false;
    m = mv;
    return true;
  }

 private:
  const Capture& capture_;
  const Layer& layer_;
  const Parameterization& dst_;
  Mat3 dst_to_src_;
  std::once_flag once_;
  std::optional<TexelSource> colour_, mask_;
};

}  // namespace

Image merge_captures(const std::vector<Capture>& captures, const Parameterization& dst, const Mat3& dst_to_world,
                     MergeReport* report, const ResampleOptions& options) {
  if (captures.empty()) throw Error("nothing to merge: no captures");
  const int W = dst.width(), H = dst.height();
  const std::size_t texels = std::size_t(W) * H;
  const TexelDirections dirs(dst);
  const SolidAngleTable omega(dst);
  std::vector<double> num(texels * 3, 0.0), den(texels, 0.0), mask_max(texels, 0.0);
  std::vector<std::vector<float>> weights(captures.size()), seen_by(captures.size());
  ResampleOptions opt = options;
  opt.filter = Filter::Area;
  bool any_whole = false;
  for (std::size_t k = 0; k < captures.size(); ++k) {
    const Capture& c = captures[k];
    const Footprint footprint(c.map);
    const Layer layer = layer_of(c, footprint, dst, dst_to_world, opt);
    any_whole = any_whole || footprint.whole_sphere();
    const Image& r = layer.colour;
    const int C = r.channels - (r.alpha_channel >= 0 ? 1 : 0);
    const Mat3 dst_to_src = compose(transposed(c.map.to_world()), dst_to_world);
    weights[k].assign(texels, 0.0f);
    seen_by[k].assign(texels, 0.0f);
    // The capture's mean solid angle per pixel, for texels whose centre it does not see (their edge): built on
    // first use, a solid-angle table of a disk costs an integral per texel.
    std::once_flag mean_once;
    double mean_per_pixel = 0.0;
    SliverReader sliver(c, layer, dst, dst_to_world);
    tbb::parallel_for(0, H, [&](int j) {
      for (int i = 0; i < W; ++i) {
        const std::size_t t = std::size_t(j) * W + i;
        const double coverage = layer.coverage[t];
        if (!(coverage > 0.0)) continue;
        double rgb[3], m;
        const bool reached = r.alpha_channel < 0 || r.at(i, j, r.alpha_channel) > 0.0f;
        if (reached) {
          for (int ch = 0; ch < 3; ++ch) rgb[ch] = r.at(i, j, C == 1 ? 0 : ch);
          m = layer.mask.empty() ? 1.0 : double(layer.mask.at(i, j, 0));
        } else {
          // A sliver: the resampler's sub-samples missed what the capture
          // sees of this texel; read the capture where the quadrature saw it.
          Vec2 q(0.0, 0.0);
          const CoverageIntegrator in(dst, dst_to_world, [&footprint](const Vec3& d) { return footprint.sees(d); });
          if (!(in.fraction(i, j, &q) > 0.0) || !sliver.read(q, rgb, m)) continue;
        }
        m = std::clamp(m, 0.0, 1.0);
        const double seen = coverage * m;
        if (!(seen > 0.0)) continue;
        Vec3 d;
        if (!dirs.centre(i, j, d)) {
          Vec2 q;
          if (!dst.covered_point(i, j, q) || !dst.to_direction(q, d)) continue;
        }
        // Sampling density where the capture sees the texel centre; a centre
        // just outside a capture that sees part of the texel takes the
        // capture's mean density instead.
        const Vec2 p = c.map.param->to_image(apply(dst_to_src, d));
        const bool inside = p.x >= 0 && p.y >= 0 && p.x <= c.map.image.width && p.y <= c.map.image.height;
        double per_pixel = inside ? c.map.param->solid_angle_density(p) : 0.0;
        if (!(per_pixel > 0.0)) {
          std::call_once(mean_once, [&] {  // isolated, as in SliverReader
            tbb::this_task_arena::isolate([&] {
              mean_per_pixel = SolidAngleTable(*c.map.param).total() / (double(c.map.image.width) * c.map.image.height);
            });
          });
          per_pixel = mean_per_pixel;
        }
        const double w = seen / per_pixel;
        // Colour x mask over mask: the capture's radiance averaged over the
        // part of the texel its mask keeps.
        for (int ch = 0; ch < 3; ++ch) num[t * 3 + ch] += w * (c.exposure * rgb[ch] / m);
        den[t] += w;
        mask_max[t] = std::max(mask_max[t], m);
        weights[k][t] = float(w);
        seen_by[k][t] = float(seen);
      }
    });
  }
  // Alpha: the part of each texel some capture sees (their union, exactly),
  // times the largest mask mean among them.
  std::vector<double> union_coverage;
  if (any_whole) {
    union_coverage = whole_coverage(dst);
  } else {
    std::vector<Footprint> footprints;
    std::vector<Vec3> landmarks;
    for (const Capture& c : captures) {
      footprints.emplace_back(c.map);
      for (const Vec3& d : footprints.back().landmarks()) landmarks.push_back(d);
    }
    union_coverage = coverage_fractions(
        dst, dst_to_world,
        [&footprints](const Vec3& d) {
          return std::any_of(footprints.begin(), footprints.end(), [&d](const Footprint& f) { return f.sees(d); });
        },
        landmarks);
  }
  Image out(W, H, 4);
  out.channel_names = {"R", "G", "B", "A"};
  out.alpha_channel = 3;
  out.metadata = captures[0].map.image.metadata;
  double uncovered = 0.0;
  std::vector<double> covered(captures.size(), 0.0), share(captures.size(), 0.0);
  double total_weight = 0.0;
  for (int j = 0; j < H; ++j)
    for (int i = 0; i < W; ++i) {
      const std::size_t t = std::size_t(j) * W + i;
      const double o = omega(i, j);
      const double alpha = den[t] > 0.0 ? union_coverage[t] * mask_max[t] : 0.0;
      uncovered += o * (1.0 - alpha);
      for (std::size_t k = 0; k < captures.size(); ++k) covered[k] += o * seen_by[k][t];
      if (den[t] > 0.0) {
        for (int ch = 0; ch < 3; ++ch) out.at(i, j, ch) = float(num[t * 3 + ch] / den[t]);
        out.at(i, j, 3) = float(alpha);
        for (std::size_t k = 0; k < captures.size(); ++k) {
          const double w = weights[k][t] / den[t] * o;
          share[k] += w;
          total_weight += w;
        }
      }
    }
  if (report) {
    report->uncovered_solid_angle = uncovered;
    for (std::size_t k = 0; k < captures.size(); ++k) share[k] = total_weight > 0.0 ? share[k] / total_weight : 0.0;
    report->weight_share = share;
    report->covered_solid_angle = covered;
  }
  return out;
}

}  // namespace envkit
