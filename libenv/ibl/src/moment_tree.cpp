#include "moment_tree.h"

#include <envkit/core/error.h>
#include <envkit/core/huge_page_allocator.h>
#include <envkit/maps/cubemap.h>
#include <envkit/maps/solid_angle_table.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/resample/filter.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace envkit::detail {

namespace {

using Moments6 = std::array<double, 6>;

// x in the even bits, y in the odd bits: the four children of node n are 4n .. 4n + 3.
std::uint32_t spread_bits(std::uint32_t x) {
  x &= 0xFFFFu;
  x = (x | (x << 8)) & 0x00FF00FFu;
  x = (x | (x << 4)) & 0x0F0F0F0Fu;
  x = (x | (x << 2)) & 0x33333333u;
  x = (x | (x << 1)) & 0x55555555u;
  return x;
}
std::uint32_t morton(std::uint32_t i, std::uint32_t j) { return spread_bits(i) | (spread_bits(j) << 1); }

std::size_t families_at(int level) { return level == 0 ? 2 : std::size_t(6) << (2 * (level - 1)); }

// The outer product d d^T in the order of the moments.
Moments6 outer(const Vec3& d) { return {d.x * d.x, d.y * d.y, d.z * d.z, d.x * d.y, d.x * d.z, d.y * d.z}; }

// One node's sums as the builder forms them, in double.
struct NodeSums {
  std::array<double, 4> flux{};
  double omega = 0.0;
  double weight = 0.0;  // sum of |flux| over the colour channels: the weight of flux_mean
  Vec3 flux_mean{0.0}, omega_mean{0.0};
  Moments6 flux_cov{}, omega_cov{};
};

NodeSums read_lane(const NodeFamily& f, int q, int channels, int alpha_channel) {
  NodeSums s;
  for (int c = 0; c < 4; ++c) s.flux[c] = f.flux[c][q];
  for (int c = 0; c < channels; ++c)
    if (c != alpha_channel) s.weight += std::abs(s.flux[c]);
  s.omega = f.omega[q];
  s.flux_mean = Vec3(f.flux_mean[0][q], f.flux_mean[1][q], f.flux_mean[2][q]);
  s.omega_mean = Vec3(f.omega_mean[0][q], f.omega_mean[1][q], f.omega_mean[2][q]);
  for (int e = 0; e < 6; ++e) {
    s.flux_cov[e] = f.flux_cov[e][q];
    s.omega_cov[e] = f.omega_cov[e][q];
  }
  return s;
}

// The gap 1 - |m|^2 of the mean as stored (float), so that 1 - r . m = (|r - m|^2 + gap) / 2 holds for the stored m.
float gap_of(const Float4 (&m)[3], int q) {
  const double x = m[0][q], y = m[1][q], z = m[2][q];
  return float(std::max(0.0, 1.0 - (x * x + y * y + z * z)));
}

void write_lane(NodeFamily& f, int q, const NodeSums& s) {
  for (int c = 0; c < 4; ++c) f.flux[c][q] = float(s.flux[c]);
  f.omega[q] = float(s.omega);
  for (int a = 0; a < 3; ++a) {
    f.flux_mean[a][q] = float(s.flux_mean[a]);
    f.omega_mean[a][q] = float(s.omega_mean[a]);
  }
  f.flux_gap[q] = gap_of(f.flux_mean, q);
  f.omega_gap[q] = gap_of(f.omega_mean, q);
  for (int e = 0; e < 6; ++e) {
    f.flux_cov[e][q] = float(s.flux_cov[e]);
    f.omega_cov[e][q] = float(s.omega_cov[e]);
  }
}

// A lane that no walk can reach: its mean is the origin (1 - r . mean = 1, so nothing of it is summed) and it holds
// nothing.
void write_empty_lane(NodeFamily& f, int q) {
  NodeSums empty;
  write_lane(f, q, empty);
}

// The parent of four children by the parallel-axis rule, C = sum w_i (C_i + (m_i - m)(m_i - m)^T) / sum w_i, which has
// no cancellation. Means of unit vectors are not re-normalised: r . mean is the exact mean of r . l over the node.
NodeSums combine(const std::array<NodeSums, 4>& child) {
  NodeSums p;
  for (const NodeSums& c : child) {
    for (int k = 0; k < 4; ++k) p.flux[k] += c.flux[k];
    p.omega += c.omega;
    p.weight += c.weight;
    p.flux_mean += c.weight * c.flux_mean;
    p.omega_mean += c.omega * c.omega_mean;
  }
  p.omega_mean = p.omega > 0.0 ? p.omega_mean / p.omega : Vec3(0.0);
  p.flux_mean = p.weight > 0.0 ? p.flux_mean / p.weight : p.omega_mean;
  for (const NodeSums& c : child) {
    const Moments6 sf = outer(c.flux_mean - p.flux_mean), so = outer(c.omega_mean - p.omega_mean);
    for (int e = 0; e < 6; ++e) {
      p.flux_cov[e] += c.weight * (c.flux_cov[e] + sf[e]);
      p.omega_cov[e] += c.omega * (c.omega_cov[e] + so[e]);
    }
  }
  for (int e = 0; e < 6; ++e) {
    p.omega_cov[e] = p.omega > 0.0 ? p.omega_cov[e] / p.omega : 0.0;
    p.flux_cov[e] = p.weight > 0.0 ? p.flux_cov[e] / p.weight : p.omega_cov[e];
  }
  return p;
}

// ---- The walk's arithmetic, four lanes at a time ----

Float4 splat(double v) { return Float4{} + float(v); }
Float4 keep(Int4 mask, Float4 v) { return (Float4)(mask & (Int4)v); }
Float4 at_least_zero(Float4 v) { return keep(v > Float4{}, v); }
int lanes_of(Int4 mask) { return (mask[0] & 1) | (mask[1] & 2) | (mask[2] & 4) | (mask[3] & 8); }

// e = 1 - r . mean for the four means of m, from |r - m|^2 and the stored gap (exact to float precision near the
// lobe's peak, where e is tiny and r . m would have lost it).
Float4 one_minus_dot(const Float4 (&m)[3], Float4 gap, Float4 rx, Float4 ry, Float4 rz) {
  const Float4 dx = rx - m[0], dy = ry - m[1], dz = rz - m[2];
  return 0.5f * (dx * dx + dy * dy + dz * dz + gap);
}

// The same for the unit directions of the means (finest nodes that act as points).
Float4 one_minus_dot_unit(const Float4 (&m)[3], Float4 rx, Float4 ry, Float4 rz) {
  Float4 len2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
  Float4 inv;
  for (int q = 0; q < 4; ++q) inv[q] = len2[q] > 0.0f ? 1.0f / std::sqrt(len2[q]) : 0.0f;
  const Float4 dx = rx - m[0] * inv, dy = ry - m[1] * inv, dz = rz - m[2] * inv;
  return 0.5f * (dx * dx + dy * dy + dz * dz + keep(len2 <= Float4{}, splat(1.0)));
}

// The split-sum weight D(n.h) (n.l) at c = r.l = 1 - e, without the constant 1/pi, which the normalisation cancels
// (n = v = r, (n.h)^2 = (1 + c) / 2): a^2 c / t^2 with t = a^2 + e (1 - a^2) / 2. Zero for c <= 0.
struct Lobe {
  Float4 a2, half_one_minus_a2, k;  // k = (a^2 - 1) / 2
  Float4 t(Float4 e) const { return a2 + e * half_one_minus_a2; }
  Float4 weight(Float4 e) const {
    const Float4 c = 1.0f - e, tt = t(e);
    return keep(c > Float4{}, a2 * c / (tt * tt));
  }
  // weight + weight''(c) var / 2, the second-order mean over a node whose r . d has variance var; at least 0.
  Float4 weight_over(Float4 e, Float4 var) const {
    const Float4 c = 1.0f - e, tt = t(e), t3 = tt * tt * tt;
    const Float4 curvature = a2 * (-4.0f * k / t3 + 6.0f * c * k * k / (t3 * tt));
    return keep(c > Float4{}, at_least_zero(weight(e) + 0.5f * curvature * var));
  }
};

Float4 quad_form(const Float4 (&m)[6], Float4 x, Float4 y, Float4 z) {
  return at_least_zero(x * x * m[0] + y * y * m[1] + z * z * m[2] +
                       2.0f * (x * y * m[3] + x * z * m[4] + y * z * m[5]));
}

// A node's sums over its texels, in float: a node holds a few dozen texels, and the directions enter as offsets
// from the node's centre, whose moments keep float's digits (raw moments of d would lose them to the
// subtraction of the mean below). Half the memory of doubles, which a big gather pays for in page faults.
struct Acc {
  std::array<float, 4> flux;
  float omega, weight;
  std::array<float, 3> flux_sum, omega_sum;  // of (d - centre), weighted
  std::array<float, 6> flux_m2, omega_m2;    // of (d - centre)(d - centre)^T, weighted
};

}  // namespace

double MomentTree::texel_radius(int size) { return std::atan(std::sqrt(2.0) / double(size)); }

double MomentTree::peak_bytes(int face_size) {
  // Every level's families (a geometric series: 4/3 of the finest level's) and the gather's sums per finest node.
  const double finest_nodes = 6.0 * double(face_size) * double(face_size);
  return finest_nodes * (sizeof(NodeFamily) / 4.0 * 4.0 / 3.0 + sizeof(Acc));
}

MomentTree::MomentTree(const MapRef& src, int face_size, bool keep_texels)
    : channels_(src.image.channels), alpha_channel_(src.image.alpha_channel) {
  if (face_size < 1 || face_size > kMaxFaceSize || (face_size & (face_size - 1)) != 0)
    throw Error("prefilter: source size must be a power of two up to 16384, not " + std::to_string(face_size));
  if (channels_ > 4) throw Error("prefilter: at most 4 channels");
  while ((1 << finest_) < face_size) ++finest_;
  levels_.resize(finest_ + 1);
  for (int k = 0; k <= finest_; ++k) {
    levels_[k].resize(families_at(k));
    radius_.push_back(texel_radius(1 << k));
  }
  gather(src, face_size, keep_texels);
  sum_upward();
}

void MomentTree::gather(const MapRef& src, int face_size, bool keep_texels) {
  const CubeMap cube(face_size, CubeLayout::VerticalStrip, CubeBasis::GL, TexelGrid::Centre);
  const int w = src.image.width, h = src.image.height, channels = src.image.channels;
  const int alpha_channel = src.image.alpha_channel;
  const TexelDirections dirs(src.param);
  const SolidAngleTable omega(src.param);
  const TexelSource coverage(src.image, src.param);
  // The centre of a finest node: the centre of its texel on the gathering cube.
  auto centre_of = [&](int i, int row) {
    Vec3 c;
    cube.to_direction(Vec2(i + 0.5, row + 0.5), c);
    return c;
  };
  // Source texel (x, y) as the gather sees it: its unit direction in the world frame and exact solid angle; false
  // where the map holds no data.
  auto source_texel = [&](int x, int y, Vec3& d, double& o) {
    if (!coverage.covered(std::size_t(y) * w + x) || !dirs.centre(x, y, d)) return false;
    o = omega(x, y);
    if (!(o > 0.0)) return false;
    d = apply(src.to_world, d).normalized();
    return true;
  };
  const std::uint32_t face_nodes = std::uint32_t(face_size) * std::uint32_t(face_size);
  // With keep_texels, the finest node of every source texel (UINT32_MAX without data), for the texel lists.
  std::vector<std::uint32_t> node_of(keep_texels ? std::size_t(w) * h : 0, UINT32_MAX);
  // Source rows in fixed bands, each band gathering into its own run-length list; bands merge in order, so the sums
  // do not depend on the thread count. Chunks of bands at a time bound the memory of the lists, and the chunks
  // reuse the same lists (fresh ones would fault in new pages for every chunk).
  const int bands = std::min(h, 256), chunk = 16;
  std::vector<Acc, UninitialisedAllocator<Acc>> acc(std::size_t(6) * face_nodes);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, acc.size()), [&](const tbb::blocked_range<std::size_t>& r) {
    std::fill(acc.begin() + r.begin(), acc.begin() + r.end(), Acc{});
  });
  std::vector<std::vector<std::pair<std::uint32_t, Acc>>> partial(chunk);
  for (int b0 = 0; b0 < bands; b0 += chunk) {
    tbb::parallel_for(b0, std::min(bands, b0 + chunk), [&](int b) {
      const int y0 = int(std::int64_t(h) * b / bands), y1 = int(std::int64_t(h) * (b + 1) / bands);
      std::vector<std::pair<std::uint32_t, Acc>>& out = partial[b - b0];
      out.clear();
      std::uint32_t last = UINT32_MAX;
      Vec3 centre(0.0);
      for (int y = y0; y < y1; ++y)
        for (int x = 0; x < w; ++x) {
          const std::size_t index = std::size_t(y) * w + x;
          Vec3 d;
          double o = 0.0;
          if (!source_texel(x, y, d, o)) continue;
          const Vec2 pos = cube.to_image(d);
          const int i = std::clamp(int(pos.x), 0, face_size - 1);
          const int row = std::clamp(int(pos.y), 0, 6 * face_size - 1);
          const std::uint32_t node =
              std::uint32_t(row / face_size) * face_nodes + morton(std::uint32_t(i), std::uint32_t(row % face_size));
          if (keep_texels) node_of[index] = node;
          if (node != last) {
            out.push_back({node, Acc{}});
            last = node;
            centre = centre_of(i, row);
          }
          Acc& a = out.back().second;
          const float* px = src.image.pixels.data() + index * channels;
          double lum = 0.0;
          for (int c = 0; c < channels; ++c) {
            a.flux[c] += float(double(px[c]) * o);
            if (c != alpha_channel) lum += std::abs(double(px[c]));
          }
          const Vec3 off = d - centre;
          const double lo = lum * o;
          a.omega += float(o);
          a.weight += float(lo);
          for (int e = 0; e < 3; ++e) {
            a.omega_sum[e] += float(o * off[e]);
            a.flux_sum[e] += float(lo * off[e]);
          }
          const Moments6 dd = outer(off);
          for (int q = 0; q < 6; ++q) {
            a.omega_m2[q] += float(o * dd[q]);
            a.flux_m2[q] += float(lo * dd[q]);
          }
        }
    });
    for (int b = b0; b < std::min(bands, b0 + chunk); ++b) {
      for (const auto& [t, a] : partial[b - b0]) {
        Acc& to = acc[t];
        for (int c = 0; c < 4; ++c) to.flux[c] += a.flux[c];
        to.omega += a.omega;
        to.weight += a.weight;
        for (int e = 0; e < 3; ++e) {
          to.omega_sum[e] += a.omega_sum[e];
          to.flux_sum[e] += a.flux_sum[e];
        }
        for (int q = 0; q < 6; ++q) {
          to.omega_m2[q] += a.omega_m2[q];
          to.flux_m2[q] += a.flux_m2[q];
        }
      }
    }
  }
  if (keep_texels) {
    // Counting sort by node, in source order within a node: the lists do not depend on the thread count.
    first_texel_.assign(acc.size() + 1, 0);
    for (const std::uint32_t node : node_of)
      if (node != UINT32_MAX) ++first_texel_[node + 1];
    for (std::size_t n = 0; n < acc.size(); ++n) first_texel_[n + 1] += first_texel_[n];
    std::vector<std::uint32_t> slot(first_texel_.begin(), first_texel_.end() - 1), order(first_texel_.back());
    for (std::size_t index = 0; index < node_of.size(); ++index)
      if (node_of[index] != UINT32_MAX) order[slot[node_of[index]]++] = std::uint32_t(index);
    texels_.resize(order.size());
    tbb::parallel_for(std::size_t(0), order.size(), [&](std::size_t k) {
      const int x = int(order[k] % std::uint32_t(w)), y = int(order[k] / std::uint32_t(w));
      Vec3 d(0.0);
      double o = 0.0;
      source_texel(x, y, d, o);  // listed, so it holds data
      Texel& t = texels_[k];
      t = Texel{{float(d.x), float(d.y), float(d.z)}, {}, float(o)};
      const float* px = src.image.pixels.data() + std::size_t(order[k]) * channels;
      for (int c = 0; c < channels; ++c) t.flux[c] = float(double(px[c]) * o);
    });
  }
  // Mean offsets and central moments from the offsets' sums, in double.
  auto mean_offset = [](const std::array<float, 3>& sum, double weight) {
    return weight > 0.0 ? Vec3(sum[0], sum[1], sum[2]) / weight : Vec3(0.0);
  };
  auto central = [](const std::array<float, 6>& sum_dd, double weight, const Vec3& mean_off) {
    Moments6 c{};
    if (!(weight > 0.0)) return c;
    const Moments6 mm = outer(mean_off);
    for (int e = 0; e < 6; ++e) c[e] = double(sum_dd[e]) / weight - mm[e];
    for (int e = 0; e < 3; ++e) c[e] = std::max(c[e], 0.0);  // variances, >= 0 but for rounding
    return c;
  };
  auto& finest = levels_[finest_];
  tbb::parallel_for(std::size_t(0), finest.size(), [&](std::size_t fam) {
    for (int q = 0; q < 4; ++q) {
      const std::uint32_t node = std::uint32_t(fam * 4 + q);
      const Acc& a = acc[node];
      NodeSums s;
      for (int c = 0; c < 4; ++c) s.flux[c] = a.flux[c];
      s.omega = a.omega;
      s.weight = a.weight;
      if (s.omega > 0.0) {
        const std::uint32_t f = node / face_nodes, m = node % face_nodes;
        std::uint32_t i = 0, j = 0;
        for (int bit = 0; bit < 16; ++bit) {  // Morton index back to (i, j)
          i |= ((m >> (2 * bit)) & 1u) << bit;
          j |= ((m >> (2 * bit + 1)) & 1u) << bit;
        }
        const Vec3 centre = centre_of(int(i), int(f * std::uint32_t(face_size) + j));
        const Vec3 om = mean_offset(a.omega_sum, s.omega);
        const Vec3 fm = s.weight > 0.0 ? mean_offset(a.flux_sum, s.weight) : om;
        s.omega_mean = centre + om;
        s.flux_mean = centre + fm;
        s.omega_cov = central(a.omega_m2, s.omega, om);
        s.flux_cov = s.weight > 0.0 ? central(a.flux_m2, s.weight, fm) : s.omega_cov;
      }
      write_lane(finest[fam], q, s);
    }
  });
}

void MomentTree::sum_upward() {
  for (int k = finest_ - 1; k >= 0; --k) {
    const auto& fine = levels_[k + 1];
    auto& coarse = levels_[k];
    tbb::parallel_for(std::size_t(0), coarse.size(), [&](std::size_t fam) {
      for (int q = 0; q < 4; ++q) {
        const std::size_t node = fam * 4 + q;  // node of level k = family of level k + 1
        if (node >= fine.size()) {
          write_empty_lane(coarse[fam], q);
          continue;
        }
        std::array<NodeSums, 4> child;
        for (int c = 0; c < 4; ++c) child[c] = read_lane(fine[node], c, channels_, alpha_channel_);
        write_lane(coarse[fam], q, combine(child));
      }
    });
  }
}

MomentTree::Walk MomentTree::walk(double alpha, double accuracy) const {
  Walk w;
  w.alpha = alpha;
  const double spread = 2.0 * alpha;
  // A second-order expansion over a node wider than the lobe would be wrong. Where texels are kept, a finest node
  // refines into them by the same rule as any node into its children; without, finest nodes wider than the lobe
  // act as points, and narrower ones take the second-order term like every other node.
  const bool texels = !texels_.empty();
  w.finest_points = !texels && radius_[finest_] > accuracy * spread;
  // Per level:
  // - skip: wholly below the horizon of r (every point of a node lies within 2 rho of its mean): c < -sin(2 rho);
  // - straddles: across the horizon, where the weight has its kink (no second-order term there);
  // - refine: a node of radius rho at chord distance d = sqrt(2 e) from r, t = d + spread, is refined while
  //   rho > accuracy t (t / spread)^(1/6), i.e. t^7 < (rho / accuracy)^6 spread. Its second-order term errs by about
  //   (rho / t)^3 of its own weight, and the nodes at distance ~t hold a fraction ~(spread / t)^2 of the lobe's
  //   weight, so each ring's share of the error still falls as (spread / t)^(3/2) while the node count per ring
  //   falls as (spread / t)^(1/3) (docs/PREFILTER.md has the exponents tried). Nodes across the horizon also refine
  //   while larger than 0.25 accuracy / alpha.
  for (int k = 0; k <= finest_; ++k) {
    const double edge = std::sin(std::min(2.0 * radius_[k], kPi / 2));
    w.skip_above[k] = float(1.0 + edge);
    w.straddle_above[k] = float(1.0 - edge);
    const double q = radius_[k] / accuracy, q2 = q * q;
    const double limit = std::pow(q2 * q2 * q2 * spread, 1.0 / 7.0) - spread;  // t < limit + spread
    const bool refinable = k < finest_ || texels;
    w.refine_below[k] = refinable && limit > 0.0 ? float(0.5 * limit * limit) : -1.0f;
    w.horizon_refine[k] = refinable && radius_[k] > 0.25 * accuracy / alpha;
  }
  return w;
}

void MomentTree::filter(const Walk& walk, std::span<const Vec3> r, std::span<float> out) const {
  const int n = int(r.size());
  if (n < 1 || n > kMaxGroup || out.size() < r.size() * std::size_t(channels_))
    throw Error("prefilter: a group of 1 to " + std::to_string(kMaxGroup) + " directions");
  const double a2 = walk.alpha * walk.alpha;
  const Lobe lobe{splat(a2), splat(0.5 * (1.0 - a2)), splat(0.5 * (a2 - 1.0))};
  struct Direction {
    Float4 x, y, z;
  };
  std::array<Direction, kMaxGroup> dir;
  for (int t = 0; t < n; ++t) dir[t] = {splat(r[t].x), splat(r[t].y), splat(r[t].z)};
  std::array<std::array<Float4, 4>, kMaxGroup> acc{};
  std::array<Float4, kMaxGroup> weight{};
  struct Item {
    int level;
    std::uint32_t family;
  };
  // Depth-first: at most 4 families wait per level.
  std::array<Item, 4 * 33> stack;
  int top = 0;
  stack[top++] = {0, 1};
  stack[top++] = {0, 0};
  // The texels of a finest node, four at a time in the lanes, each a point at its own direction (the brute-force
  // sum's own terms); lanes past the last texel hold nothing.
  auto sum_texels = [&](std::uint32_t node) {
    for (std::uint32_t k = first_texel_[node]; k < first_texel_[node + 1]; k += 4) {
      Float4 m[3] = {}, flux[4] = {}, omega = {};
      for (std::uint32_t q = 0; q < 4 && k + q < first_texel_[node + 1]; ++q) {
        const Texel& tx = texels_[k + q];
        for (int a = 0; a < 3; ++a) m[a][q] = tx.d[a];
        for (int c = 0; c < channels_; ++c) flux[c][q] = tx.flux[c];
        omega[q] = tx.omega;
      }
      for (int t = 0; t < n; ++t) {
        const Float4 wt = lobe.weight(one_minus_dot(m, Float4{}, dir[t].x, dir[t].y, dir[t].z));
        for (int c = 0; c < channels_; ++c) acc[t][c] += wt * flux[c];
        weight[t] += wt * omega;
      }
    }
  };
  std::array<Float4, kMaxGroup> eo;
  std::array<Int4, kMaxGroup> visible, straddles;
  while (top > 0) {
    const Item it = stack[--top];
    const NodeFamily& f = levels_[it.level][it.family];
    const bool points = walk.finest_points && it.level == finest_;
    // A node is refined for the whole group when any direction needs it refined: the others then sum its children,
    // which is finer than they need and never less exact.
    Int4 refine = {};
    for (int t = 0; t < n; ++t) {
      const Direction& d = dir[t];
      eo[t] = points ? one_minus_dot_unit(f.omega_mean, d.x, d.y, d.z)
                     : one_minus_dot(f.omega_mean, f.omega_gap, d.x, d.y, d.z);
      visible[t] = eo[t] <= splat(walk.skip_above[it.level]);
      straddles[t] = eo[t] > splat(walk.straddle_above[it.level]);
      Int4 wants = eo[t] < splat(walk.refine_below[it.level]);
      if (walk.horizon_refine[it.level]) wants |= straddles[t];
      refine |= wants & visible[t];
    }
    for (int t = 0; t < n; ++t) {
      const Int4 summed = visible[t] & ~refine;
      if (!lanes_of(summed)) continue;
      const Direction& d = dir[t];
      Float4 wf, wo;
      if (points) {
        wf = lobe.weight(one_minus_dot_unit(f.flux_mean, d.x, d.y, d.z));
        wo = lobe.weight(eo[t]);
      } else {
        const Float4 ef = one_minus_dot(f.flux_mean, f.flux_gap, d.x, d.y, d.z);
        // The second-order term over the node, E[w(c)] ~ w(E c) + w''(E c) Var(c) / 2; not across the horizon.
        const Float4 vf = keep(~straddles[t], quad_form(f.flux_cov, d.x, d.y, d.z));
        const Float4 vo = keep(~straddles[t], quad_form(f.omega_cov, d.x, d.y, d.z));
        wf = lobe.weight_over(ef, vf);
        wo = lobe.weight_over(eo[t], vo);
      }
      wf = keep(summed, wf);
      for (int c = 0; c < channels_; ++c) acc[t][c] += wf * f.flux[c];
      weight[t] += keep(summed, wo) * f.omega;
    }
    const int refined = lanes_of(refine);
    for (int q = 0; q < 4; ++q)
      if (refined & (1 << q)) {
        const std::uint32_t child = it.family * 4 + std::uint32_t(q);
        if (it.level == finest_)
          sum_texels(child);
        else if (child < levels_[it.level + 1].size())
          stack[top++] = {it.level + 1, child};
      }
  }
  for (int t = 0; t < n; ++t) {
    double total_weight = 0.0;
    for (int q = 0; q < 4; ++q) total_weight += weight[t][q];
    for (int c = 0; c < channels_; ++c) {
      double sum = 0.0;
      for (int q = 0; q < 4; ++q) sum += acc[t][c][q];
      const double v = total_weight > 0.0 ? sum / total_weight : 0.0;
      out[std::size_t(t) * channels_ + c] = std::isfinite(v) ? float(v) : 0.0f;
    }
  }
}

}  // namespace envkit::detail
