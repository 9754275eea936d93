// Each output tile's source texels, by a first pass over the source, row by row (scatter_tile_ranges.h). Each texel is
// projected and given the tiles its square's cells lie in: the whole span floor(x0)..floor(x0 + width) on each axis
// (a superset of the cells it gives a share), resolved across the output's charts as its shares are; its column
// widens the range its row keeps for each of those tiles. A range is kept in plain columns or turned by half the row
// (whichever is shorter), so that a tile across a lat-long's seam does not take the whole row.
#include "scatter_tile_ranges.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <memory>
#include <vector>

#include "resample_common.h"

// Last: its target attribute applies to the functions that use it.
#include <envkit/core/simd/avx2_target.h>

namespace envkit::detail {

namespace {

/// One row's texels that reach one tile, kept while the row is scanned: their columns' range, and the same range
/// with the columns turned by half the row.
struct RowReach {
  int tile, lo, hi, turned_lo, turned_hi;
};

/// A texel's tile code: kNone without shares, kExact where the texel must be looked at closely.
constexpr int kNone = -1, kExact = -2;

/// Largest value of a table over a range of its entries, in constant time (a sparse table of maxima over runs of
/// 2^k entries).
class RangeMax {
 public:
  explicit RangeMax(std::vector<double> values) {
    levels_.push_back(std::move(values));
    const std::size_t n = levels_[0].size();
    for (std::size_t run = 2; run <= n; run *= 2) {
      const std::vector<double>& below = levels_.back();
      std::vector<double> level(n - run + 1);
      for (std::size_t i = 0; i < level.size(); ++i) level[i] = std::max(below[i], below[i + run / 2]);
      levels_.push_back(std::move(level));
    }
  }
  /// The largest of entries [first, last].
  double operator()(int first, int last) const {
    const int k = std::bit_width(unsigned(last - first + 1)) - 1;
    return std::max(levels_[k][first], levels_[k][last - (1 << k) + 1]);
  }

 private:
  std::vector<std::vector<double>> levels_;
};

/// The bound a row's texels are settled by: a box about each texel's centre at least as large as its square, half a
/// side hx (hy) each way, from the row's largest source texel and the largest scale of the output rows the row
/// reaches, plus a margin far above the rounding of the square's own corners. The box's corner cells are found with
/// the offset +16 (the box reaches at most 4 texels past the image), so that truncation is floor. The texel's code is
/// the tile when the box's cells lie in one tile (inside the image and, when tiles are aligned to the blocks in which
/// taps resolve to themselves, in the anchor's block, since the box holds the anchor), else kExact; kNone when the
/// centre lies outside the output's image.
struct TileBox {
  double hx, hy;
  int DW, DH, tiles_x;
  bool aligned;
  static constexpr double kMargin = 1e-6, kOffset = 16.0;

  int code(double px, double py) const {
    const bool lands = !(px < 0.0 || py < 0.0 || px > DW || py > DH);
    const int cx0 = static_cast<int>(px - hx + kOffset) - 16, cx1 = static_cast<int>(px + hx + kOffset) - 16;
    const int cy0 = static_cast<int>(py - hy + kOffset) - 16, cy1 = static_cast<int>(py + hy + kOffset) - 16;
    const bool one_tile = aligned && (cx0 >> kTileBits) == (cx1 >> kTileBits) &&
                          (cy0 >> kTileBits) == (cy1 >> kTileBits) && cx0 >= 0 && cy0 >= 0 && cx1 < DW && cy1 < DH;
    return !lands ? kNone : one_tile ? (cy0 >> kTileBits) * tiles_x + (cx0 >> kTileBits) : kExact;
  }
};

#if defined(ENVKIT_AVX2)
/// TileBox::code's cell of a box edge: truncation of v + 16, less 16.
ENVKIT_AVX2 inline __m128i cell_avx2(__m256d v) {
  return _mm_sub_epi32(_mm256_cvttpd_epi32(_mm256_add_pd(v, _mm256_set1_pd(TileBox::kOffset))), _mm_set1_epi32(16));
}

/// The least and largest of y[0, n rounded down to 4), with y_low and y_high; returns how many it read.
ENVKIT_AVX2 int y_range_avx2(const double* y, int n, double& y_low, double& y_high) {
  __m256d low = _mm256_set1_pd(y_low), high = _mm256_set1_pd(y_high);
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    const __m256d v = _mm256_loadu_pd(y + i);
    low = _mm256_min_pd(low, v);
    high = _mm256_max_pd(high, v);
  }
  alignas(32) double l[4], h[4];
  _mm256_store_pd(l, low);
  _mm256_store_pd(h, high);
  y_low = std::min({l[0], l[1], l[2], l[3]});
  y_high = std::max({h[0], h[1], h[2], h[3]});
  return i;
}

/// TileBox::code of texels [0, n rounded down to 4) on AVX2 lanes, the same operations (so the same codes); returns
/// how many it did.
ENVKIT_AVX2 int tile_codes_avx2(const TileBox& b, const double* x, const double* y, int n, int* code) {
  const __m256d zero = _mm256_setzero_pd(), dw = _mm256_set1_pd(b.DW), dh = _mm256_set1_pd(b.DH);
  const __m256d hx = _mm256_set1_pd(b.hx), hy = _mm256_set1_pd(b.hy);
  const __m128i izero = _mm_setzero_si128(), width = _mm_set1_epi32(b.DW), height = _mm_set1_epi32(b.DH);
  const __m128i tiles_x = _mm_set1_epi32(b.tiles_x), none = _mm_set1_epi32(kNone), exact = _mm_set1_epi32(kExact);
  const __m128i aligned = _mm_set1_epi32(b.aligned ? -1 : 0);
  const __m256i low_halves = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    const __m256d px = _mm256_loadu_pd(x + i), py = _mm256_loadu_pd(y + i);
    const __m256d out =
        _mm256_or_pd(_mm256_or_pd(_mm256_cmp_pd(px, zero, _CMP_LT_OQ), _mm256_cmp_pd(py, zero, _CMP_LT_OQ)),
                     _mm256_or_pd(_mm256_cmp_pd(px, dw, _CMP_GT_OQ), _mm256_cmp_pd(py, dh, _CMP_GT_OQ)));
    const __m128i cx0 = cell_avx2(_mm256_sub_pd(px, hx)), cx1 = cell_avx2(_mm256_add_pd(px, hx));
    const __m128i cy0 = cell_avx2(_mm256_sub_pd(py, hy)), cy1 = cell_avx2(_mm256_add_pd(py, hy));
    const __m128i tx0 = _mm_srai_epi32(cx0, kTileBits), ty0 = _mm_srai_epi32(cy0, kTileBits);
    __m128i one = _mm_and_si128(aligned, _mm_cmpeq_epi32(tx0, _mm_srai_epi32(cx1, kTileBits)));
    one = _mm_and_si128(one, _mm_cmpeq_epi32(ty0, _mm_srai_epi32(cy1, kTileBits)));
    one = _mm_andnot_si128(_mm_or_si128(_mm_cmplt_epi32(cx0, izero), _mm_cmplt_epi32(cy0, izero)), one);
    one = _mm_and_si128(one, _mm_and_si128(_mm_cmplt_epi32(cx1, width), _mm_cmplt_epi32(cy1, height)));
    const __m128i tile = _mm_add_epi32(_mm_mullo_epi32(ty0, tiles_x), tx0);
    // The low halves of the 64-bit masks, as 32-bit masks.
    const __m128i outside = _mm256_castsi256_si128(_mm256_permutevar8x32_epi32(_mm256_castpd_si256(out), low_halves));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(code + i),
                     _mm_blendv_epi8(_mm_blendv_epi8(exact, tile, one), none, outside));
  }
  return i;
}
#endif

/// What bounds square() over ranges of output rows: per row the largest scale along x and y (ScatterGeometry's
/// row scales, or its largest 1 / sqrt(omega)) and the least side (1 where a texel without solid angle is in the row).
struct SquareBounds {
  RangeMax scale_x, scale_y, least;
  explicit SquareBounds(const ScatterGeometry& g)
      : scale_x(row_values(g, 0)), scale_y(row_values(g, 1)), least(row_values(g, 2)) {}

 private:
  static std::vector<double> row_values(const ScatterGeometry& g, int which) {
    std::vector<double> v(g.DH, 0.0);
    tbb::parallel_for(0, g.DH, [&](int tj) {
      if (!g.row_scales.x.empty()) {
        v[tj] = which == 0 ? g.row_scales.x[tj] : which == 1 ? g.row_scales.y[tj] : 0.0;
        return;
      }
      float largest = 0.0f;
      bool unsized = false;
      for (int ti = 0; ti < g.DW; ++ti) {
        const float inverse = g.inverse_side[std::size_t(tj) * g.DW + ti];
        largest = std::max(largest, inverse);
        unsized = unsized || !(inverse > 0.0f);  // square() gives such a texel's squares a side of 1
      }
      v[tj] = which == 2 ? (unsized ? 1.0 : 0.0) : largest;
    });
    return v;
  }
};

/// Per source row, the tiles its texels' squares reach, each with a column range. A row is scanned by one thread; the
/// result depends only on the row.
///
/// Most texels are settled by a bound: a box about the texel's centre at least as large as its square (from the
/// row's largest source texel and the output row's largest texel scale), whose cells all lie in one tile of the
/// anchor's chart. The rest (near a tile's or a chart's edge) take their exact square and resolve each of its cells
/// as the shares do.
class RowReaches {
 public:
  RowReaches(const ScatterGeometry& g, const SquareBounds& bounds, int tiles_x, int tiles, bool lanes)
      : g_(g),
        bounds_(bounds),
        tiles_x_(tiles_x),
        lanes_(lanes),
        aligned_(output_tiles_aligned(g.dst)),
        slot_(tiles, -1),
        x_(g.W),
        y_(g.W),
        code_(g.W) {}

  /// The tiles source row j reaches, as ranges (start, count) in plain columns.
  void scan(int j, std::vector<ColumnRange>& out, std::vector<int>& tiles_out) {
    const int W = g_.W, half = W / 2, DW = g_.DW, DH = g_.DH;
    const double row_omega = g_.omega_per_row ? g_.src_omega(1, j) : 0.0;
    double largest_omega = 0.0;
    if (g_.omega_per_row)
      largest_omega = std::max({row_omega, g_.src_omega(0, j), g_.src_omega(W - 1, j)});
    else
      for (int i = 0; i < W; ++i) largest_omega = std::max(largest_omega, g_.source_omega(i, j, row_omega));
    const double root = std::sqrt(largest_omega);
    if (g_.rows) {
      g_.rows->project(j, 0, W, x_.data(), y_.data());
    } else {
      for (int i = 0; i < W; ++i) {
        Vec2 p;
        if (!g_.project(i, j, p)) p = Vec2(-1.0, -1.0);  // outside: no shares
        x_[i] = p.x;
        y_[i] = p.y;
      }
    }
    // The output rows the row's centres lie on bound its squares' scale.
    double y_low = DH, y_high = 0.0;
    int k = 0;
#if defined(ENVKIT_AVX2)
    if (lanes_) k = y_range_avx2(y_.data(), W, y_low, y_high);
#endif
    for (; k < W; ++k) {
      y_low = std::min(y_low, y_[k]);
      y_high = std::max(y_high, y_[k]);
    }
    const int tj0 = std::clamp(static_cast<int>(std::max(y_low, 0.0)), 0, DH - 1);
    const int tj1 = std::clamp(static_cast<int>(std::min(y_high, double(DH))), tj0, DH - 1);
    const double least = bounds_.least(tj0, tj1);
    const auto half_side = [&](const RangeMax& scale) {
      return 0.5 * std::max(std::min(root * scale(tj0, tj1), kMaxSideInTexels), least) + TileBox::kMargin;
    };
    const TileBox box{half_side(bounds_.scale_x), half_side(bounds_.scale_y), DW, DH, tiles_x_, aligned_};
    int i = 0;
#if defined(ENVKIT_AVX2)
    if (lanes_) i = tile_codes_avx2(box, x_.data(), y_.data(), W, code_.data());
#endif
    for (; i < W; ++i) code_[i] = box.code(x_[i], y_[i]);
    // Texels without solid angle have no shares.
    if (g_.omega_per_row) {
      if (!(row_omega > 0.0)) std::fill(code_.begin(), code_.end(), kNone);
      if (!(g_.src_omega(0, j) > 0.0)) code_[0] = kNone;
      if (!(g_.src_omega(W - 1, j) > 0.0)) code_[W - 1] = kNone;
    } else {
      for (int c = 0; c < W; ++c)
        if (!(g_.source_omega(c, j, row_omega) > 0.0)) code_[c] = kNone;
    }
    reach_.clear();
    Parameterization::TapBlock block;
    for (i = 0; i < W; ++i) {
      const int code = code_[i];
      if (code == kNone) continue;
      if (code >= 0) {
        // A run of texels settled in one tile widens its range by the run's ends (and the columns either side of
        // the turned columns' wrap, when the run holds it).
        int last = i;
        while (last + 1 < W && code_[last + 1] == code) ++last;
        mark(code, i, W, half);
        if (i < W - half && last >= W - half) {
          if (i < W - half - 1) mark(code, W - half - 1, W, half);
          if (last > W - half) mark(code, W - half, W, half);
        }
        if (last > i) mark(code, last, W, half);
        i = last;
        continue;
      }
      // As the shares compute them: the texel's square, its corner and far side, each cell resolved.
      const Vec2 p(x_[i], y_[i]);
      const int ti = std::clamp(static_cast<int>(p.x), 0, DW - 1);
      const int tj = std::clamp(static_cast<int>(p.y), 0, DH - 1);
      double width, height;
      g_.square(std::sqrt(g_.source_omega(i, j, row_omega)), ti, tj, width, height);
      const double x0 = p.x - 0.5 * width, y0 = p.y - 0.5 * height;
      const int ex0 = static_cast<int>(std::floor(x0)), ex1 = static_cast<int>(std::floor(x0 + width));
      const int ey0 = static_cast<int>(std::floor(y0)), ey1 = static_cast<int>(std::floor(y0 + height));
      if (!block.holds(ti, tj)) block = g_.dst.tap_block(ti, tj);
      for (int cj = ey0; cj <= ey1; ++cj)
        for (int ci = ex0; ci <= ex1; ++ci) {
          int ri = ci, rj = cj;
          if (!block.holds(ri, rj) && !g_.dst.resolve(ti, tj, ri, rj)) continue;
          mark((rj >> kTileBits) * tiles_x_ + (ri >> kTileBits), i, W, half);
        }
    }
    for (const RowReach& r : reach_) {
      slot_[r.tile] = -1;
      const int plain = r.hi - r.lo + 1, turned = r.turned_hi - r.turned_lo + 1;
      if (turned < plain) {
        const int start = r.turned_lo < half ? r.turned_lo + (W - half) : r.turned_lo - half;
        out.push_back({j, start, turned});
      } else {
        out.push_back({j, r.lo, plain});
      }
      tiles_out.push_back(r.tile);
    }
  }

 private:
  /// Widens `tile`'s column range on this row by column i (columns come in increasing order).
  void mark(int tile, int i, int W, int half) {
    const int t = i < W - half ? i + half : i - (W - half);  // the column turned by half the row
    int& s = slot_[tile];
    if (s < 0) {
      s = static_cast<int>(reach_.size());
      reach_.push_back({tile, i, i, t, t});
      return;
    }
    RowReach& r = reach_[s];
    r.hi = i;
    r.turned_lo = std::min(r.turned_lo, t);
    r.turned_hi = std::max(r.turned_hi, t);
  }

  const ScatterGeometry& g_;
  const SquareBounds& bounds_;
  int tiles_x_;
  bool lanes_;
  bool aligned_;           // whether a box in one tile is in one block (output_tiles_aligned)
  std::vector<int> slot_;  // per tile: its entry in reach_, or -1
  std::vector<RowReach> reach_;
  std::vector<double> x_, y_;
  std::vector<int> code_;
};

}  // namespace

bool output_tiles_aligned(const Parameterization& dst) {
  const int tc = dst.tap_cell();
  return tc == 0 || (tc > 0 && tc % kTile == 0);
}

TileRanges tile_ranges(const ScatterGeometry& g, bool lanes) {
  const int H = g.src.height();
  TileRanges t;
  t.tiles_x = (g.DW + kTile - 1) / kTile;
  t.tiles = t.tiles_x * ((g.DH + kTile - 1) / kTile);
  // Per source row, the tiles it reaches and the column range that reaches each.
  std::vector<std::vector<ColumnRange>> row_ranges(H);
  std::vector<std::vector<int>> row_tiles(H);
  {
    const SquareBounds bounds(g);
    tbb::enumerable_thread_specific<std::unique_ptr<RowReaches>> scanners;
    tbb::parallel_for(tbb::blocked_range<int>(0, H, 8), [&](const tbb::blocked_range<int>& r) {
      auto& scanner = scanners.local();
      if (!scanner) scanner = std::make_unique<RowReaches>(g, bounds, t.tiles_x, t.tiles, lanes);
      for (int j = r.begin(); j < r.end(); ++j) scanner->scan(j, row_ranges[j], row_tiles[j]);
    });
  }
  // Each tile's ranges, in source row order.
  t.first.assign(std::size_t(t.tiles) + 1, 0);
  for (int j = 0; j < H; ++j)
    for (int tile : row_tiles[j]) ++t.first[std::size_t(tile) + 1];
  for (int tile = 0; tile < t.tiles; ++tile) t.first[std::size_t(tile) + 1] += t.first[tile];
  t.ranges.resize(t.first[t.tiles]);
  std::vector<std::size_t> next(t.first.begin(), t.first.end() - 1);
  for (int j = 0; j < H; ++j) {
    for (std::size_t k = 0; k < row_tiles[j].size(); ++k) t.ranges[next[row_tiles[j][k]]++] = row_ranges[j][k];
    std::vector<ColumnRange>().swap(row_ranges[j]);
    std::vector<int>().swap(row_tiles[j]);
  }
  return t;
}

}  // namespace envkit::detail
