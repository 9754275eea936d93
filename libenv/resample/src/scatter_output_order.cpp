// The area scatter summed in output order (resample_common.h, ScatterKernel::OutputOrder): the output is cut into
// tiles, and each tile sums, in a tile-sized accumulator, the shares that fall in it of every source texel whose
// square can reach it. The shares are ShareLister's (scatter_shares.h), the same as the chunked scatter's.
//
// Which source texels can reach a tile comes from a first pass over the source (scatter_tile_ranges.h): one range of
// columns per source row, holding every texel with a share whose resolved cell lies in the tile. Each tile keeps only
// the shares that fall in it, so every share is counted once.
//
// Each tile adds its shares in a fixed order (source rows in order, each row's range from its first column, each
// texel's cells in listing order), whatever the thread count; tiles write disjoint output texels.
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <memory>
#include <vector>

#include "resample_common.h"
#include "scatter_shares.h"
#include "scatter_tile_ranges.h"

namespace envkit::detail {

namespace {

/// A tile's shares summed in double: C flux-weighted channel sums, then the weight, per texel.
struct TileSums {
  int x0, y0, w, h;
  std::vector<double> sums;
  bool holds(int i, int j) const { return i >= x0 && i < x0 + w && j >= y0 && j < y0 + h; }
};

/// Adds shares to a tile's sums: those whose resolved cell lies in the tile. kC: the channel count, or 0 for any.
template <int kC>
class TileSink {
 public:
  TileSink(const Parameterization& dst, int channels, TileSums& tile)
      : dst_(dst), C_(kC > 0 ? kC : channels), tile_(tile), zeros_(std::size_t(C_), 0.0f) {}

  /// Listed shares, in list order.
  void operator()(const Contribution* list, int n) {
    for (int k = 0; k < n; ++k) {
      const Contribution& e = list[k];
      if (!block_.holds(e.anchor_i, e.anchor_j)) block_ = dst_.tap_block(e.anchor_i, e.anchor_j);
      int ci = e.cell_i, cj = e.cell_j;
      if (!block_.holds(ci, cj) && !dst_.resolve(e.anchor_i, e.anchor_j, ci, cj)) continue;
      if (!tile_.holds(ci, cj)) continue;
      add(sums_at(ci - tile_.x0, cj - tile_.y0), e.weight, e.pixel);
    }
  }

  /// The lanes' 2 x 2 shares of texel k: added at once when all four cells lie in the tile and in the anchor's block
  /// (so resolve to themselves); a share not listed adds +0 to a sum that cannot be -0 (the sums start at +0), which
  /// leaves it as it was. Otherwise as listed.
  void quad(const Shares& s, int k, int ti, int tj, unsigned listed, const float* px) {
    const int ci = s.ci[k], cj = s.cj[k];
    const unsigned x = unsigned(ci - tile_.x0), y = unsigned(cj - tile_.y0);
    if (!block_.holds(ti, tj)) block_ = dst_.tap_block(ti, tj);
    if (x < unsigned(tile_.w - 1) && y < unsigned(tile_.h - 1) && block_.holds(ci, cj) && block_.holds(ci + 1, cj + 1))
        [[likely]] {
      const int stride = C_ + 1;
      double* s00 = sums_at(int(x), int(y));
      double* s01 = s00 + std::size_t(tile_.w) * stride;
      const float* zero = zeros_.data();
      add(s00, s.w00[k], px);
      add(s00 + stride, listed & 1 ? s.w10[k] : 0.0, listed & 1 ? px : zero);
      add(s01, listed & 2 ? s.w01[k] : 0.0, listed & 2 ? px : zero);
      add(s01 + stride, listed & 4 ? s.w11[k] : 0.0, listed & 4 ? px : zero);
      return;
    }
    Contribution list[4];
    int n = 0;
    list[n++] = {ci, cj, ti, tj, s.w00[k], px};
    if (listed & 1) list[n++] = {ci + 1, cj, ti, tj, s.w10[k], px};
    if (listed & 2) list[n++] = {ci, cj + 1, ti, tj, s.w01[k], px};
    if (listed & 4) list[n++] = {ci + 1, cj + 1, ti, tj, s.w11[k], px};
    (*this)(list, n);
  }

 private:
  double* sums_at(int x, int y) { return tile_.sums.data() + (std::size_t(y) * tile_.w + std::size_t(x)) * (C_ + 1); }
  void add(double* sum, double weight, const float* px) const {
    const int C = kC > 0 ? kC : C_;
    for (int c = 0; c < C; ++c) sum[c] += weight * px[c];
    sum[C] += weight;
  }

  const Parameterization& dst_;
  int C_;
  TileSums& tile_;
  std::vector<float> zeros_;
  Parameterization::TapBlock block_;
};

}  // namespace

void scatter_in_output_order(const MapRef& s, const Parameterization& dst, const SolidAngleTable& src_omega,
                             const SolidAngleTable& dst_omega, const std::vector<std::size_t>& hot,
                             const Mat3& dst_to_src, bool lanes, ProgressCounter& progress, Image& out) {
  const Image& img = s.image;
  const int C = img.channels, W = img.width, H = img.height, Co = out.channels;
  const int DW = dst.width(), DH = dst.height();
  const ScatterGeometry g(s.param, dst, src_omega, dst_omega, dst_to_src);

  // Pass 1: each tile's ranges of source texels.
  const TileRanges reach = tile_ranges(g, lanes);
  const int tiles_x = reach.tiles_x, tiles = reach.tiles;
  const std::vector<std::size_t>& first = reach.first;
  const std::vector<ColumnRange>& ranges = reach.ranges;

  // Hot texels' channels with zero colour, alpha kept: their squares hand out weight only (they are splatted exactly
  // afterwards).
  const std::vector<float> hot_copies = hot_weight_copies(img, hot.data(), hot.data() + hot.size());

  // Pass 2: each tile's shares, summed in the tile, normalised into the output.
  struct Scratch {
    std::unique_ptr<ShareLister> lister;
    TileSums tile;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  const int stride = C + 1;
  tbb::parallel_for(tbb::blocked_range<int>(0, tiles, 1), [&](const tbb::blocked_range<int>& r) {
    Scratch& sc = scratch.local();
    if (!sc.lister) sc.lister = std::make_unique<ShareLister>(g, lanes);
    TileSums& tile = sc.tile;
    TileSink<3> sink3(dst, C, tile);
    TileSink<4> sink4(dst, C, tile);
    TileSink<0> sink(dst, C, tile);
    for (int t = r.begin(); t < r.end(); ++t) {
      tile.x0 = (t % tiles_x) * kTile;
      tile.y0 = (t / tiles_x) * kTile;
      tile.w = std::min(kTile, DW - tile.x0);
      tile.h = std::min(kTile, DH - tile.y0);
      tile.sums.assign(std::size_t(tile.w) * tile.h * stride, 0.0);
      for (std::size_t k = first[t]; k < first[std::size_t(t) + 1]; ++k) {
        const ColumnRange& cr = ranges[k];
        const int end = cr.start + cr.count;
        const int parts[2][2] = {{cr.start, std::min(end, W)}, {0, end - W}};
        for (const auto& part : parts) {
          if (part[1] <= part[0]) continue;
          const std::size_t row = std::size_t(cr.row) * W;
          const auto h0 = std::lower_bound(hot.begin(), hot.end(), row + part[0]);
          const auto h1 = std::lower_bound(h0, hot.end(), row + part[1]);
          HotCursor cursor{hot.data() + (h0 - hot.begin()), hot.data() + (h1 - hot.begin()),
                           hot_copies.data() + std::size_t(h0 - hot.begin()) * C, C};
          if (C == 3)
            sc.lister->texels(img, cr.row, part[0], part[1], cursor, sink3);
          else if (C == 4)
            sc.lister->texels(img, cr.row, part[0], part[1], cursor, sink4);
          else
            sc.lister->texels(img, cr.row, part[0], part[1], cursor, sink);
        }
      }
      for (int y = 0; y < tile.h; ++y)
        for (int x = 0; x < tile.w; ++x) {
          const int ti = tile.x0 + x, tj = tile.y0 + y;
          if (dst_omega(ti, tj) <= 0.0) continue;
          const double* sum = tile.sums.data() + (std::size_t(y) * tile.w + x) * stride;
          float* px = out.pixels.data() + (std::size_t(tj) * DW + ti) * Co;
          if (sum[C] > 0.0) {
            for (int c = 0; c < C; ++c) px[c] = static_cast<float>(sum[c] / sum[C]);
            continue;
          }
          nearest_source_texel(s, dst, dst_to_src, hot, ti, tj, px);
        }
      progress.add(std::size_t(H) * (t + 1) / tiles - std::size_t(H) * t / tiles);
    }
  });
}

}  // namespace envkit::detail
