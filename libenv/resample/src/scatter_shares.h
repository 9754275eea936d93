#pragma once
// The area scatter's shares (resample.h; what they are: docs/PARAMETERIZATIONS.md): where a source texel lands in
// the output, its square, and the share of its solid angle each output cell under the square gets. Both ways of
// summing them use this: by chunks of source rows (resample_scatter.cpp) and by tiles of the output
// (scatter_output_order.cpp). Private to libenv's resample group.
#include <envkit/maps/solid_angle_table.h>
#include <envkit/maps/texel_directions.h>
#include <envkit/resample/resample.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <memory>
#include <utility>
#include <vector>

#include "cube_projection.h"

namespace envkit::detail {

/// A source texel's square is at most this many output texels wide (a rim texel of a mirror-ball output can
/// see a whole source texel's worth of directions); its flux is still conserved, spread over the capped square.
constexpr double kMaxSideInTexels = 8.0;
constexpr int kMaxSplatCellsPerAxis = static_cast<int>(kMaxSideInTexels) + 2;

/// Output pixels per radian along x and y for each row of a lat-long output, whose texels are far from square near
/// the poles (a parallel's texels are narrow there): a source texel's square is stretched accordingly. Empty for
/// other outputs, whose texels are close enough to square.
struct RowScales {
  std::vector<double> x, y;
};
RowScales latlong_row_scales(const Parameterization& dst);

/// Fraction of [lo, hi) inside cell [c, c + 1), for each cell the interval touches; returns the first cell.
inline int overlaps(double lo, double hi, double* fraction, int& count) {
  const int first = static_cast<int>(std::floor(lo));
  if (hi <= first + 1.0) {  // inside one cell
    fraction[0] = 1.0;
    count = 1;
    return first;
  }
  const double inverse = 1.0 / (hi - lo);
  if (hi <= first + 2.0) {  // across one cell edge: the usual case when shrinking
    fraction[0] = (first + 1.0 - lo) * inverse;
    fraction[1] = 1.0 - fraction[0];
    count = 2;
    return first;
  }
  count = 0;
  for (int c = first; c < hi; ++c) fraction[count++] = (std::min(hi, c + 1.0) - std::max(lo, double(c))) * inverse;
  return first;
}

/// One share of a source texel's flux: output cell (before resolving across charts), the output texel under the
/// source texel's centre (the anchor the cell is resolved from), the share's solid angle and the texel's channels.
struct Contribution {
  int cell_i, cell_j, anchor_i, anchor_j;
  double weight;
  const float* pixel;
};

/// Contributions listed before they are added: a batch of source texels at a time, so that listing them (projection
/// and overlap fractions, without branches on where a square lies) and adding them each run as one tight loop. Sized
/// for one batch: up to four shares per texel, or a whole capped square for the rare large one.
constexpr int kBatchTexels = 512;
constexpr int kContributionCapacity = 4 * kBatchTexels + kMaxSplatCellsPerAxis * kMaxSplatCellsPerAxis;

/// The texels of a batch, projected (by columns, for the vector lanes): each centre's output position, solid angle,
/// output texel and channels.
constexpr int kBatchLanes = 4;  // the shares' vector width (AVX2 doubles); batches are padded to a multiple of it
struct Landed {
  alignas(32) double x[kBatchTexels + kBatchLanes], y[kBatchTexels + kBatchLanes], omega[kBatchTexels + kBatchLanes];
  alignas(32) int ti[kBatchTexels + kBatchLanes], tj[kBatchTexels + kBatchLanes];
  const float* pixel[kBatchTexels + kBatchLanes];
};

/// What the lanes compute of each landed texel whose square is at most one output texel on a side (flag `big`
/// clear): the cell holding the square's corner and the four shares (omega fx fy) of the 2 x 2 cells from it, with
/// the flags that say which of the last three are listed (fx fy > 0). Bit k % 4 of word k / 4 is texel k's.
struct Shares {
  alignas(32) double w00[kBatchTexels + kBatchLanes], w10[kBatchTexels + kBatchLanes], w01[kBatchTexels + kBatchLanes],
      w11[kBatchTexels + kBatchLanes];
  alignas(16) int ci[kBatchTexels + kBatchLanes], cj[kBatchTexels + kBatchLanes];
  unsigned char big[kBatchTexels / kBatchLanes + 1], f10[kBatchTexels / kBatchLanes + 1],
      f01[kBatchTexels / kBatchLanes + 1], f11[kBatchTexels / kBatchLanes + 1];
};

/// The shares of landed texels [0, m) (m a multiple of the lane count) into an output whose texels are close to
/// square (no row scales), on AVX2 lanes, to the scalar code's doubles bit for bit. Call only when use_avx2().
void shares_avx2(const Landed& l, int m, const float* inverse_side, int DW, Shares& s);

/// What projecting a source texel needs: both maps, the rotation between them and the output texels' sizes.
struct ScatterGeometry {
  const Parameterization& src;
  const Parameterization& dst;
  const SolidAngleTable& src_omega;
  Mat3 src_to_dst;
  bool rotate;
  TexelDirections directions;
  RowScales row_scales;
  FloatBuffer inverse_side;  // 1 / sqrt(omega) of each output texel, unless row_scales holds the lat-long rows'
  bool omega_per_row;        // lat-long texels of a row share one solid angle but the first and last (corner grids)
  int W, DW, DH;
  std::unique_ptr<LatLongRowsInCube> rows;  // lat-long source rows projected into a cube output at once, else null

  ScatterGeometry(const Parameterization& s, const Parameterization& d, const SolidAngleTable& s_omega,
                  const SolidAngleTable& d_omega, const Mat3& dst_to_src);

  /// Solid angle of source texel (i, j); `row_omega` is src_omega(1, j) where omega_per_row.
  double source_omega(int i, int j, double row_omega) const {
    return omega_per_row && i > 0 && i < W - 1 ? row_omega : src_omega(i, j);
  }
  /// Output position of the centre of source texel (i, j); false where it has no data or falls outside a view.
  bool project(int i, int j, Vec2& p) const {
    Vec3 d;
    if (!directions.centre(i, j, d)) return false;
    p = dst.to_image(rotate ? apply(src_to_dst, d) : d);
    return inside(p);
  }
  /// Whether an output position lies in the output's image (a view maps directions it does not see outside it).
  bool inside(Vec2 p) const { return !(p.x < 0.0 || p.y < 0.0 || p.x > DW || p.y > DH); }
  /// Starts loading what square() reads for output texel (ti, tj) (a hint: changes nothing).
  void prefetch_square(int ti, int tj) const {
    if (row_scales.x.empty()) __builtin_prefetch(inverse_side.data() + std::size_t(tj) * DW + ti);
  }
  /// The source texel's square, sqrt(omega_s) on a side, in output pixels (stretched on lat-long rows), for the
  /// output texel (ti, tj) under its centre.
  void square(double root_omega_s, int ti, int tj, double& width, double& height) const {
    if (!row_scales.x.empty()) {
      width = std::min(root_omega_s * row_scales.x[tj], kMaxSideInTexels);
      height = std::min(root_omega_s * row_scales.y[tj], kMaxSideInTexels);
    } else {
      const double inverse = inverse_side[std::size_t(tj) * DW + ti];
      width = height = inverse > 0.0 ? std::min(root_omega_s * inverse, kMaxSideInTexels) : 1.0;
    }
  }
};

/// Hot texels (splatted exactly afterwards) met in increasing source index: each is given a copy of its channels
/// with zero colour (alpha kept), so that its square still hands out its weight. `copies` holds C floats per texel
/// of [next, end), in that order.
struct HotCursor {
  const std::size_t* next = nullptr;
  const std::size_t* end = nullptr;
  const float* copies = nullptr;
  int channels = 0;
  const float* pixel(std::size_t index, const float* own) {
    if (next != end && *next == index) [[unlikely]] {
      ++next;
      const float* copy = copies;
      copies += channels;
      return copy;
    }
    return own;
  }
};

/// HotCursor's copies for the hot texels [begin, end) of img: C floats each, zero but for the alpha channel's value.
std::vector<float> hot_weight_copies(const Image& img, const std::size_t* begin, const std::size_t* end);

/// Lists source texels' shares a batch at a time: pass 1 projects the batch (whole lat-long rows into a cube on the
/// lanes of LatLongRowsInCube), pass 2 gives each landed texel's shares. A square at most one output texel on a side
/// overlaps the 2 x 2 cells from the one holding its corner; their fractions are computed alike for every such square
/// (on AVX2 lanes when `lanes` and the output has no row scales, to the same doubles) and the shares that are zero
/// are dropped from the list by its count, not by branches. Larger squares take the per-axis overlap loop. The list
/// goes to `add(list, n)` in the order of the texels, and of the cells row by row within a texel. A sink with
/// `quad(shares, k, ti, tj, listed, pixel)` takes the lanes' 2 x 2 shares of landed texel k (anchor (ti, tj))
/// directly instead, bits 0-2 of `listed` saying whether the last three are listed (f10, f01, f11); each
/// texel's shares still reach the sink in the texels' order.
class ShareLister {
 public:
  ShareLister(const ScatterGeometry& g, bool lanes);

  /// Texels [i_begin, i_end) of source row j.
  template <class Add>
  void texels(const Image& img, int j, int i_begin, int i_end, HotCursor& hot, Add&& add);

 private:
  /// Lists landed texel k's shares by the per-axis loop (any square; the only way for one wider than a texel).
  void overlap_shares(int k, int& n);

  const ScatterGeometry& g_;
  bool lanes_;
  std::vector<Contribution> list_;
  std::unique_ptr<Landed> landed_;
  std::unique_ptr<Shares> shares_;
  std::vector<double> row_x_, row_y_;
};

template <class Add>
void ShareLister::texels(const Image& img, int j, int i_begin, int i_end, HotCursor& hot, Add&& add) {
  const int C = img.channels, W = g_.W;
  const double row_omega = g_.omega_per_row ? g_.src_omega(1, j) : 0.0;
  Contribution* list = list_.data();
  Landed& l = *landed_;
  for (int i0 = i_begin; i0 < i_end; i0 += kBatchTexels) {
    // Pass 1: where each texel lands. The output texel sizes it needs are then loaded while the rest projects.
    const int i1 = std::min(i_end, i0 + kBatchTexels);
    if (g_.rows) g_.rows->project(j, i0, i1, row_x_.data(), row_y_.data());
    int m = 0;
    for (int i = i0; i < i1; ++i) {
      const std::size_t index = std::size_t(j) * W + i;
      const float* px = hot.pixel(index, img.pixels.data() + index * C);
      const double omega_s = g_.source_omega(i, j, row_omega);
      Vec2 p;
      if (g_.rows) {
        p = Vec2(row_x_[i - i0], row_y_[i - i0]);
        if (omega_s <= 0.0 || !g_.inside(p)) continue;
      } else if (omega_s <= 0.0 || !g_.project(i, j, p)) {
        continue;
      }
      const int ti = std::clamp(static_cast<int>(p.x), 0, g_.DW - 1);
      const int tj = std::clamp(static_cast<int>(p.y), 0, g_.DH - 1);
      g_.prefetch_square(ti, tj);
      l.x[m] = p.x;
      l.y[m] = p.y;
      l.omega[m] = omega_s;
      l.ti[m] = ti;
      l.tj[m] = tj;
      l.pixel[m] = px;
      ++m;
    }
    // Pass 2: each landed texel's shares.
    int n = 0;
    if (lanes_) {
      // Lanes past m hold a harmless texel (output texel 0, solid angle 1): their shares are never listed.
      const int padded = (m + kBatchLanes - 1) / kBatchLanes * kBatchLanes;
      for (int k = m; k < padded; ++k) {
        l.x[k] = l.y[k] = 0.5;
        l.omega[k] = 1.0;
        l.ti[k] = l.tj[k] = 0;
      }
      Shares& s = *shares_;
      shares_avx2(l, padded, g_.inverse_side.data(), g_.DW, s);
      for (int k = 0; k < m; ++k) {
        if (n > kContributionCapacity - kMaxSplatCellsPerAxis * kMaxSplatCellsPerAxis) [[unlikely]] {
          add(list, n);  // room for one more texel's shares, however large its square
          n = 0;
        }
        const int word = k / kBatchLanes, bit = k % kBatchLanes;
        if ((s.big[word] >> bit) & 1) [[unlikely]] {
          overlap_shares(k, n);
          continue;
        }
        const int ti = l.ti[k], tj = l.tj[k];
        if constexpr (requires { add.quad(std::as_const(s), k, ti, tj, 0u, l.pixel[k]); }) {
          // The sink takes the 2 x 2 shares as they are, after what is listed before them.
          if (n > 0) [[unlikely]] {
            add(list, n);
            n = 0;
          }
          const unsigned listed =
              ((s.f10[word] >> bit) & 1) | ((s.f01[word] >> bit) & 1) << 1 | ((s.f11[word] >> bit) & 1) << 2;
          add.quad(std::as_const(s), k, ti, tj, listed, l.pixel[k]);
          continue;
        }
        const int ci = s.ci[k], cj = s.cj[k];
        const float* px = l.pixel[k];
        list[n] = {ci, cj, ti, tj, s.w00[k], px};
        n += 1;
        list[n] = {ci + 1, cj, ti, tj, s.w10[k], px};
        n += (s.f10[word] >> bit) & 1;
        list[n] = {ci, cj + 1, ti, tj, s.w01[k], px};
        n += (s.f01[word] >> bit) & 1;
        list[n] = {ci + 1, cj + 1, ti, tj, s.w11[k], px};
        n += (s.f11[word] >> bit) & 1;
      }
      add(list, n);
      continue;
    }
    for (int k = 0; k < m; ++k) {
      if (n > kContributionCapacity - kMaxSplatCellsPerAxis * kMaxSplatCellsPerAxis) [[unlikely]] {
        add(list, n);  // room for one more texel's shares, however large its square
        n = 0;
      }
      overlap_shares(k, n);
    }
    add(list, n);
  }
}

/// Writes into `px` (its first C channels) the source texel nearest to output texel (ti, tj)'s covered point, unless
/// it is hot: what an output texel that no square reached takes (possible only where output texels are smaller than
/// source texels).
void nearest_source_texel(const MapRef& s, const Parameterization& dst, const Mat3& dst_to_src,
                          const std::vector<std::size_t>& hot, int ti, int tj, float* px);

}  // namespace envkit::detail
