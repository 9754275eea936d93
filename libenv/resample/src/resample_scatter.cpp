// The `area` filter's scatter (see resample.h): for shrinking, each source texel is read once and its flux is
// spread over the output texels that a square of its solid angle, centred on its projection, overlaps.
#include <envkit/core/huge_page_allocator.h>
#include <envkit/core/simd/simd_level.h>
#include <envkit/maps/latlong.h>
#include <envkit/maps/texel_directions.h>
#include <tbb/blocked_range.h>
#include <tbb/concurrent_queue.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <type_traits>

#include "cube_projection.h"
#include "resample_common.h"

// Last: its target attribute applies to the functions that use it.
#include <envkit/core/simd/avx2_target.h>

namespace envkit::detail {

namespace {

/// A source texel's square is at most this many output texels wide (a rim texel of a mirror-ball output can
/// see a whole source texel's worth of directions); its flux is still conserved, spread over the capped square.
constexpr double kMaxSideInTexels = 8.0;
constexpr int kMaxSplatCellsPerAxis = static_cast<int>(kMaxSideInTexels) + 2;
/// The source is cut into chunks of at most this many rows. Chunks are projected in parallel into runs of
/// contributions (oneTBB parallel_pipeline), and the runs are added to the one accumulator serially, in row order: the
/// sums do not depend on the number of threads, and the memory is one output-sized accumulator plus the chunks in
/// flight. Chunk size depends on the source width only (never on the thread count, which would change the runs and
/// so the float sums), and the chunks in flight are capped by a scratch budget, so scratch memory is bounded
/// independently of the core count.
constexpr int kMaxRowsPerChunk = 8;
constexpr std::size_t kChunkBytes = std::size_t(8) << 20;
constexpr std::size_t kScratchBytes = std::size_t(64) << 20;
/// Float accumulators hold a handful of runs per output texel to float precision; past this many source texels per
/// output texel (on average) the sums are kept in double.
constexpr double kFloatAccumulationMaxRatio = 64.0;

/// Output pixels per radian along x and y for each row of a lat-long output, whose texels are far from square near
/// the poles (a parallel's texels are narrow there): a source texel's square is stretched accordingly. Empty for
/// other outputs, whose texels are close enough to square.
struct RowScales {
  std::vector<double> x, y;
};

RowScales latlong_row_scales(const Parameterization& dst) {
  RowScales r;
  const LatLongMap* ll = dst.latlong_geometry();
  if (!ll) return r;
  const int H = dst.height();
  r.x.resize(H);
  r.y.resize(H);
  for (int j = 0; j < H; ++j) {
    const Vec2 a = ll->domain_from_image(Vec2(0.0, j)), b = ll->domain_from_image(Vec2(1.0, j + 1.0));
    const double v = std::clamp(0.5 * (a.y + b.y), 0.0, 1.0);
    r.x[j] = 1.0 / std::max(LatLongMap::kRadiansPerU * (b.x - a.x) * std::sin(LatLongMap::polar_angle(v)), 1e-300);
    r.y[j] = 1.0 / (LatLongMap::kRadiansPerV * (b.y - a.y));
  }
  return r;
}

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
/// and overlap fractions, without branches on where a square lies) and adding them (slot look-ups) each run as one
/// tight loop. Sized for one batch: up to four shares per texel, or a whole capped square for the rare large one.
constexpr int kBatchTexels = 512;
constexpr int kContributionCapacity = 4 * kBatchTexels + kMaxSplatCellsPerAxis * kMaxSplatCellsPerAxis;

/// The batched kernel's texels of a batch, projected (by columns, for the vector lanes): each centre's output
/// position, solid angle, output texel and channels.
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

/// Slots of a chunk's accumulator (a power of two). A source row revisits the output texels the row above it
/// reached, some thousands of them across four cube faces at 8k -> 1024: the slots hold about two rows' worth, so
/// most contributions are summed in the slot (in cache) and each output texel leaves a chunk a few times at most.
constexpr int kSlotBits = 14;

/// Contributions of a chunk of source rows, summed in double (a whole polar row can land in one output texel) per
/// output texel: first in a direct-mapped accumulator of slots, keyed by output texel, then as runs (a texel whose
/// slot is taken by another leaves its sum as a run, as does every slot at the chunk's end). The runs depend only on
/// the chunk's texels, never on the thread that projected it.
struct Chunk {
  int first_row = 0, end_row = 0;
  std::vector<std::size_t> cells;      // output texel of each run
  std::vector<double> sums;            // per run: C flux-weighted channel sums, then the weight
  std::vector<std::size_t> slot_cell;  // output texel held by each slot, kEmpty when none
  std::vector<double> slot_sums;       // per slot: as sums
  std::vector<Contribution> list;      // the batched kernel's contributions of a batch of texels
  std::vector<float> hot_pixels;       // the batched kernel's copies of hot texels, colour zeroed
  std::unique_ptr<Landed> landed;      // the batched kernel's texels of a batch, projected
  std::unique_ptr<Shares> shares;      // the batched kernel's shares of a batch, from the lanes
  std::vector<double> row_x, row_y;    // the batched kernel's output positions of a batch (ScatterGeometry::rows)
  static constexpr std::size_t kEmpty = std::size_t(-1);

  void start(int first, int end, int stride) {
    first_row = first;
    end_row = end;
    cells.clear();
    sums.clear();
    slot_cell.assign(std::size_t(1) << kSlotBits, kEmpty);
    slot_sums.resize(slot_cell.size() * stride);
  }
  /// The sums of output texel `cell` (C channel sums, then the weight), zero the first time.
  double* sums_of(std::size_t cell, int stride) {
    const std::size_t slot = slot_of(cell);
    double* held = slot_sums.data() + slot * stride;
    if (slot_cell[slot] != cell) [[unlikely]]
      take(slot, cell, held, stride);
    return held;
  }
  /// Starts loading the slot of output texel `cell` into the cache (a hint: changes nothing).
  void prefetch(std::size_t cell, int stride) const {
    const std::size_t slot = slot_of(cell);
    __builtin_prefetch(slot_cell.data() + slot);
    __builtin_prefetch(slot_sums.data() + slot * stride);
  }
  static std::size_t slot_of(std::size_t cell) { return (cell * 0x9E3779B97F4A7C15ull) >> (64 - kSlotBits); }
  /// Moves what the slots hold into the runs, in slot order.
  void flush(int stride) {
    for (std::size_t slot = 0; slot < slot_cell.size(); ++slot)
      if (slot_cell[slot] != kEmpty) emit(slot_cell[slot], slot_sums.data() + slot * stride, stride);
  }

 private:
  /// Gives `slot` to `cell`, with zero sums, after moving what it held into the runs.
  [[gnu::noinline]] void take(std::size_t slot, std::size_t cell, double* held, int stride) {
    if (slot_cell[slot] != kEmpty) emit(slot_cell[slot], held, stride);
    slot_cell[slot] = cell;
    std::fill_n(held, stride, 0.0);
  }
  void emit(std::size_t cell, const double* value, int stride) {
    cells.push_back(cell);
    sums.insert(sums.end(), value, value + stride);
  }
};

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
                  const SolidAngleTable& d_omega, const Mat3& dst_to_src)
      : src(s),
        dst(d),
        src_omega(s_omega),
        src_to_dst(transposed(dst_to_src)),
        rotate(!is_identity(src_to_dst)),
        directions(s),
        row_scales(latlong_row_scales(d)),
        omega_per_row(s.latlong_geometry() != nullptr && s.width() > 2),
        W(s.width()),
        DW(d.width()),
        DH(d.height()),
        rows(LatLongRowsInCube::make(s, d, src_to_dst, rotate)) {
    if (!row_scales.x.empty()) return;
    inverse_side.resize(std::size_t(DW) * std::size_t(DH));
    tbb::parallel_for(0, DH, [&](int j) {
      for (int i = 0; i < DW; ++i) {
        const double omega = d_omega(i, j);
        inverse_side[std::size_t(j) * DW + i] = omega > 0.0 ? static_cast<float>(1.0 / std::sqrt(omega)) : 0.0f;
      }
    });
  }

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

/// The reference kernel: each source texel of a chunk in turn, its square's overlaps found by branching on where it
/// lies, each contribution added at once. Hot texels (splatted exactly afterwards) give their weight, colour zero.
void project_chunk_per_texel(const ScatterGeometry& g, const Image& img, const std::vector<std::size_t>& hot,
                             Chunk& chunk) {
  const int C = img.channels, W = g.W, DW = g.DW, stride = C + 1;
  double fx[kMaxSplatCellsPerAxis], fy[kMaxSplatCellsPerAxis];
  Parameterization::TapBlock block;  // the anchor's, kept while the anchor stays in it
  for (int j = chunk.first_row; j < chunk.end_row; ++j) {
    auto next_hot = std::lower_bound(hot.begin(), hot.end(), std::size_t(j) * W);
    const double row_omega = g.omega_per_row ? g.src_omega(1, j) : 0.0;
    for (int i = 0; i < W; ++i) {
      const std::size_t index = std::size_t(j) * W + i;
      const bool is_hot = next_hot != hot.end() && *next_hot == index;
      if (is_hot) ++next_hot;
      const double omega_s = g.source_omega(i, j, row_omega);
      Vec2 p;
      if (omega_s <= 0.0 || !g.project(i, j, p)) continue;
      const int ti = std::clamp(static_cast<int>(p.x), 0, g.DW - 1);
      const int tj = std::clamp(static_cast<int>(p.y), 0, g.DH - 1);
      double width, height;
      g.square(std::sqrt(omega_s), ti, tj, width, height);
      const float* px = img.pixels.data() + index * C;
      if (!block.holds(ti, tj)) block = g.dst.tap_block(ti, tj);
      const auto add = [&](int ci, int cj, double w) {
        if (!block.holds(ci, cj) && !g.dst.resolve(ti, tj, ci, cj)) return;
        double* run = chunk.sums_of(std::size_t(cj) * DW + ci, stride);
        for (int c = 0; c < C; ++c)
          if (!is_hot || c == img.alpha_channel) run[c] += w * px[c];
        run[C] += w;
      };
      const double x0 = p.x - 0.5 * width, y0 = p.y - 0.5 * height;
      if (x0 >= ti && y0 >= tj && x0 + width <= ti + 1 && y0 + height <= tj + 1) {
        add(ti, tj, omega_s);  // the common case: the square lies inside one output texel
        continue;
      }
      int nx, ny;
      const int cx = overlaps(x0, x0 + width, fx, nx), cy = overlaps(y0, y0 + height, fy, ny);
      for (int b = 0; b < ny; ++b)
        for (int a = 0; a < nx; ++a)
          if (fx[a] * fy[b] > 0.0) add(cx + a, cy + b, omega_s * fx[a] * fy[b]);
    }
  }
  chunk.flush(stride);
}

/// Adds the listed contributions to the chunk's sums in list order (the order the per-texel kernel adds them in, so
/// both kernels give the same runs). kC: the channel count, or 0 for any.
template <int kC>
void add_contributions(const Parameterization& dst, const Contribution* list, int n, int channels, int DW,
                       Chunk& chunk) {
  const int C = kC > 0 ? kC : channels, stride = C + 1;
  Parameterization::TapBlock block;
  // The slots are spread over the accumulator by a hash: each is likely a cache miss, so ask for them ahead.
  constexpr int kAhead = 8;
  for (int k = 0; k < std::min(n, kAhead); ++k)
    chunk.prefetch(std::size_t(list[k].cell_j) * DW + list[k].cell_i, stride);
  for (int k = 0; k < n; ++k) {
    if (k + kAhead < n) chunk.prefetch(std::size_t(list[k + kAhead].cell_j) * DW + list[k + kAhead].cell_i, stride);
    const Contribution& e = list[k];
    if (!block.holds(e.anchor_i, e.anchor_j)) block = dst.tap_block(e.anchor_i, e.anchor_j);
    int ci = e.cell_i, cj = e.cell_j;
    if (!block.holds(ci, cj) && !dst.resolve(e.anchor_i, e.anchor_j, ci, cj)) continue;
    double* run = chunk.sums_of(std::size_t(cj) * DW + ci, stride);
    for (int c = 0; c < C; ++c) run[c] += e.weight * e.pixel[c];
    run[C] += e.weight;
  }
}

#if defined(ENVKIT_AVX2)
/// The shares of landed texels [0, m) (m a multiple of the lane count) into an output whose texels are close to
/// square (no row scales), on four lanes: the scalar code's operations in its order, each exact in IEEE double (sqrt,
/// division, floor, min and products; the attribute enables AVX2 alone, so nothing is fused into an FMA), so the same
/// doubles bit for bit.
ENVKIT_AVX2 void shares_avx2(const Landed& l, int m, const float* inverse_side, int DW, Shares& s) {
  const __m256d zero = _mm256_setzero_pd(), half = _mm256_set1_pd(0.5), one = _mm256_set1_pd(1.0);
  const __m256d cap = _mm256_set1_pd(kMaxSideInTexels);
  const __m128i width = _mm_set1_epi32(DW);
  for (int k = 0; k < m; k += kBatchLanes) {
    const __m128i ti = _mm_load_si128(reinterpret_cast<const __m128i*>(l.ti + k));
    const __m128i tj = _mm_load_si128(reinterpret_cast<const __m128i*>(l.tj + k));
    // ScatterGeometry::square: inverse > 0 ? std::min(sqrt(omega) * inverse, cap) : 1, with std::min(a, cap) being
    // cap < a ? cap : a.
    const __m256d inverse =
        _mm256_cvtps_pd(_mm_i32gather_ps(inverse_side, _mm_add_epi32(_mm_mullo_epi32(tj, width), ti), 4));
    const __m256d omega = _mm256_load_pd(l.omega + k);
    const __m256d product = _mm256_mul_pd(_mm256_sqrt_pd(omega), inverse);
    const __m256d capped = _mm256_blendv_pd(product, cap, _mm256_cmp_pd(cap, product, _CMP_LT_OQ));
    const __m256d side = _mm256_blendv_pd(one, capped, _mm256_cmp_pd(inverse, zero, _CMP_GT_OQ));
    const __m256d x0 = _mm256_sub_pd(_mm256_load_pd(l.x + k), _mm256_mul_pd(half, side));
    const __m256d y0 = _mm256_sub_pd(_mm256_load_pd(l.y + k), _mm256_mul_pd(half, side));
    const __m256d cx = _mm256_floor_pd(x0), cy = _mm256_floor_pd(y0);
    const __m256d x1 = _mm256_add_pd(x0, side), y1 = _mm256_add_pd(y0, side);
    const __m256d cx1 = _mm256_add_pd(cx, one), cy1 = _mm256_add_pd(cy, one);
    const __m256d fx0 =
        _mm256_blendv_pd(_mm256_mul_pd(_mm256_sub_pd(cx1, x0), _mm256_div_pd(one, _mm256_sub_pd(x1, x0))), one,
                         _mm256_cmp_pd(x1, cx1, _CMP_LE_OQ));
    const __m256d fy0 =
        _mm256_blendv_pd(_mm256_mul_pd(_mm256_sub_pd(cy1, y0), _mm256_div_pd(one, _mm256_sub_pd(y1, y0))), one,
                         _mm256_cmp_pd(y1, cy1, _CMP_LE_OQ));
    const __m256d fx1 = _mm256_sub_pd(one, fx0), fy1 = _mm256_sub_pd(one, fy0);
    _mm256_store_pd(s.w00 + k, _mm256_mul_pd(_mm256_mul_pd(omega, fx0), fy0));
    _mm256_store_pd(s.w10 + k, _mm256_mul_pd(_mm256_mul_pd(omega, fx1), fy0));
    _mm256_store_pd(s.w01 + k, _mm256_mul_pd(_mm256_mul_pd(omega, fx0), fy1));
    _mm256_store_pd(s.w11 + k, _mm256_mul_pd(_mm256_mul_pd(omega, fx1), fy1));
    _mm_store_si128(reinterpret_cast<__m128i*>(s.ci + k), _mm256_cvttpd_epi32(cx));
    _mm_store_si128(reinterpret_cast<__m128i*>(s.cj + k), _mm256_cvttpd_epi32(cy));
    const int word = k / kBatchLanes;
    s.big[word] = static_cast<unsigned char>(_mm256_movemask_pd(_mm256_cmp_pd(side, one, _CMP_GT_OQ)));
    s.f10[word] =
        static_cast<unsigned char>(_mm256_movemask_pd(_mm256_cmp_pd(_mm256_mul_pd(fx1, fy0), zero, _CMP_GT_OQ)));
    s.f01[word] =
        static_cast<unsigned char>(_mm256_movemask_pd(_mm256_cmp_pd(_mm256_mul_pd(fx0, fy1), zero, _CMP_GT_OQ)));
    s.f11[word] =
        static_cast<unsigned char>(_mm256_movemask_pd(_mm256_cmp_pd(_mm256_mul_pd(fx1, fy1), zero, _CMP_GT_OQ)));
  }
}
#endif

/// The batched kernel: the same contributions as project_chunk_per_texel, in the same order, listed a batch of
/// texels at a time and then added. A square at most one output texel on a side overlaps the 2 x 2 cells from the
/// one holding its corner; their fractions are computed alike for every such square and the shares that are zero
/// dropped from the list by its count, not by branches. Larger squares (rare: near the poles of a lat-long output)
/// take the per-axis overlap loop. Hot texels point at a copy of their channels with zero colour. With `lanes` (and
/// an output whose texels are close to square), the shares of a batch are computed on vector lanes first, to the
/// same doubles.
void project_chunk_batched(const ScatterGeometry& g, const Image& img, const std::vector<std::size_t>& hot, bool lanes,
                           Chunk& chunk) {
  const int C = img.channels, W = g.W, stride = C + 1;
  const auto add = [&](const Contribution* list, int n) {
    if (C == 3)
      add_contributions<3>(g.dst, list, n, C, g.DW, chunk);
    else if (C == 4)
      add_contributions<4>(g.dst, list, n, C, g.DW, chunk);
    else
      add_contributions<0>(g.dst, list, n, C, g.DW, chunk);
  };
  // Hot texels' channels with zero colour, alpha kept.
  const auto hot_begin = std::lower_bound(hot.begin(), hot.end(), std::size_t(chunk.first_row) * W);
  const auto hot_end = std::lower_bound(hot.begin(), hot.end(), std::size_t(chunk.end_row) * W);
  chunk.hot_pixels.assign(std::size_t(hot_end - hot_begin) * C, 0.0f);
  for (auto h = hot_begin; h != hot_end; ++h)
    if (img.alpha_channel >= 0)
      chunk.hot_pixels[std::size_t(h - hot_begin) * C + img.alpha_channel] = img.pixels[*h * C + img.alpha_channel];
  chunk.list.resize(kContributionCapacity);
  if (!chunk.landed) chunk.landed = std::make_unique<Landed>();
#if defined(ENVKIT_AVX2)
  lanes = lanes && g.row_scales.x.empty();
  if (lanes && !chunk.shares) chunk.shares = std::make_unique<Shares>();
#else
  lanes = false;
#endif
  chunk.row_x.resize(g.rows ? kBatchTexels : 0);
  chunk.row_y.resize(chunk.row_x.size());
  Contribution* list = chunk.list.data();
  Landed& l = *chunk.landed;
  auto next_hot = hot_begin;
  double fx[kMaxSplatCellsPerAxis], fy[kMaxSplatCellsPerAxis];
  // The per-axis overlap loop of a square wider than one output texel (or any square, without the lanes).
  const auto overlap_shares = [&](int k, int& n) {
    const double px = l.x[k], py = l.y[k], omega_s = l.omega[k];
    const int ti = l.ti[k], tj = l.tj[k];
    double width, height;
    g.square(std::sqrt(omega_s), ti, tj, width, height);
    const double x0 = px - 0.5 * width, y0 = py - 0.5 * height;
    if (width > 1.0 || height > 1.0) [[unlikely]] {
      int nx, ny;
      const int cx = overlaps(x0, x0 + width, fx, nx), cy = overlaps(y0, y0 + height, fy, ny);
      for (int b = 0; b < ny; ++b)
        for (int a = 0; a < nx; ++a)
          if (fx[a] * fy[b] > 0.0) list[n++] = {cx + a, cy + b, ti, tj, omega_s * fx[a] * fy[b], l.pixel[k]};
      return;
    }
    // As overlaps(): the fraction of [x0, x0 + width) in the cell holding x0, the rest in the next cell.
    const double cx = std::floor(x0), cy = std::floor(y0);
    const double x1 = x0 + width, y1 = y0 + height;
    const double fx0 = x1 <= cx + 1.0 ? 1.0 : (cx + 1.0 - x0) * (1.0 / (x1 - x0));
    const double fy0 = y1 <= cy + 1.0 ? 1.0 : (cy + 1.0 - y0) * (1.0 / (y1 - y0));
    const double fx1 = 1.0 - fx0, fy1 = 1.0 - fy0;
    const int ci = static_cast<int>(cx), cj = static_cast<int>(cy);
    const float* px_ = l.pixel[k];
    list[n] = {ci, cj, ti, tj, omega_s * fx0 * fy0, px_};
    n += 1;
    list[n] = {ci + 1, cj, ti, tj, omega_s * fx1 * fy0, px_};
    n += fx1 * fy0 > 0.0;
    list[n] = {ci, cj + 1, ti, tj, omega_s * fx0 * fy1, px_};
    n += fx0 * fy1 > 0.0;
    list[n] = {ci + 1, cj + 1, ti, tj, omega_s * fx1 * fy1, px_};
    n += fx1 * fy1 > 0.0;
  };
  for (int j = chunk.first_row; j < chunk.end_row; ++j) {
    const double row_omega = g.omega_per_row ? g.src_omega(1, j) : 0.0;
    for (int i0 = 0; i0 < W; i0 += kBatchTexels) {
      // Pass 1: where each texel lands. The output texel sizes it needs are then loaded while the rest projects.
      const int i_end = std::min(W, i0 + kBatchTexels);
      if (g.rows) g.rows->project(j, i0, i_end, chunk.row_x.data(), chunk.row_y.data());
      int m = 0;
      for (int i = i0; i < i_end; ++i) {
        const std::size_t index = std::size_t(j) * W + i;
        const float* px = img.pixels.data() + index * C;
        if (next_hot != hot_end && *next_hot == index) [[unlikely]]
          px = chunk.hot_pixels.data() + std::size_t(next_hot++ - hot_begin) * C;
        const double omega_s = g.source_omega(i, j, row_omega);
        Vec2 p;
        if (g.rows) {
          p = Vec2(chunk.row_x[i - i0], chunk.row_y[i - i0]);
          if (omega_s <= 0.0 || !g.inside(p)) continue;
        } else if (omega_s <= 0.0 || !g.project(i, j, p)) {
          continue;
        }
        const int ti = std::clamp(static_cast<int>(p.x), 0, g.DW - 1);
        const int tj = std::clamp(static_cast<int>(p.y), 0, g.DH - 1);
        g.prefetch_square(ti, tj);
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
#if defined(ENVKIT_AVX2)
      if (lanes) {
        // Lanes past m hold a harmless texel (output texel 0, solid angle 1): their shares are never listed.
        for (int k = m; k < (m + kBatchLanes - 1) / kBatchLanes * kBatchLanes; ++k) {
          l.x[k] = l.y[k] = 0.5;
          l.omega[k] = 1.0;
          l.ti[k] = l.tj[k] = 0;
        }
        Shares& s = *chunk.shares;
        shares_avx2(l, (m + kBatchLanes - 1) / kBatchLanes * kBatchLanes, g.inverse_side.data(), g.DW, s);
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
          const int ci = s.ci[k], cj = s.cj[k], ti = l.ti[k], tj = l.tj[k];
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
#endif
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
  chunk.flush(stride);
}

template <class Real>
void scatter_and_normalise(const MapRef& s, const Parameterization& dst, const SolidAngleTable& src_omega,
                           const SolidAngleTable& dst_omega, const std::vector<std::size_t>& hot,
                           const Mat3& dst_to_src, ScatterKernel kernel, ProgressCounter& progress, Image& out) {
  const Image& img = s.image;
  const Parameterization& sp = s.param;
  const int C = img.channels, W = img.width, H = img.height;
  const int DW = dst.width(), DH = dst.height();
  const ScatterGeometry geometry(sp, dst, src_omega, dst_omega, dst_to_src);
  const int stride = C + 1;

  // Stage 2 of the pipeline: project a chunk's texels and spread each one's flux over the output texels its
  // square overlaps, summed per output texel in the chunk's slots and handed on as runs.
  const auto project = [&](Chunk& chunk) {
    if (kernel == ScatterKernel::PerTexel)
      project_chunk_per_texel(geometry, img, hot, chunk);
    else
      project_chunk_batched(geometry, img, hot, kernel == ScatterKernel::Batched && use_avx2(), chunk);
  };

  // Per output texel: the flux-weighted sum of each channel, and the weight (the solid angle received). Float sums
  // of every channel are kept in the output image itself, which is zero and normalised in place below: the only
  // fresh memory to touch is the weights.
  const int Co = out.channels;
  const bool in_output = std::is_same_v<Real, float> && Co == C;
  const auto zeroed = [](std::size_t n) {
    std::vector<Real, UninitialisedAllocator<Real>> v(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](const tbb::blocked_range<std::size_t>& r) {
      std::fill(v.begin() + r.begin(), v.begin() + r.end(), Real(0));
    });
    return v;
  };
  auto separate_sums = zeroed(in_output ? 0 : std::size_t(DW) * std::size_t(DH) * C);
  auto weight = zeroed(std::size_t(DW) * std::size_t(DH));
  Real* sum = in_output ? reinterpret_cast<Real*>(out.pixels.data()) : separate_sums.data();
  int next_row = 0;
  // Chunks are recycled: fresh buffers per chunk would page-fault all over again. A chunk's runs are at most one
  // per contribution, and in practice about one per output texel the chunk reaches.
  std::vector<std::unique_ptr<Chunk>> chunks;
  tbb::concurrent_queue<Chunk*> free_chunks;
  const std::size_t row_bytes = std::size_t(W) * (sizeof(std::size_t) + sizeof(double) * stride);
  const int rows_per_chunk =
      static_cast<int>(std::clamp<std::size_t>(kChunkBytes / std::max<std::size_t>(row_bytes, 1), 1, kMaxRowsPerChunk));
  const std::size_t chunk_bytes =
      row_bytes * rows_per_chunk + (std::size_t(1) << kSlotBits) * (sizeof(std::size_t) + sizeof(double) * stride);
  const std::size_t tokens = std::clamp<std::size_t>(
      kScratchBytes / chunk_bytes, 2,
      std::max<std::size_t>(2, 4 * static_cast<std::size_t>(tbb::this_task_arena::max_concurrency())));
  tbb::parallel_pipeline(
      tokens, tbb::make_filter<void, Chunk*>(tbb::filter_mode::serial_in_order, [&](tbb::flow_control& fc) -> Chunk* {
                if (next_row >= H) {
                  fc.stop();
                  return nullptr;
                }
                Chunk* chunk = nullptr;
                if (!free_chunks.try_pop(chunk)) {
                  chunks.push_back(std::make_unique<Chunk>());
                  chunk = chunks.back().get();
                }
                const int first = next_row;
                next_row = std::min(H, next_row + rows_per_chunk);
                chunk->start(first, next_row, stride);
                return chunk;
              }) & tbb::make_filter<Chunk*, Chunk*>(tbb::filter_mode::parallel, [&](Chunk* chunk) {
                project(*chunk);
                return chunk;
              }) & tbb::make_filter<Chunk*, void>(tbb::filter_mode::serial_in_order, [&](Chunk* chunk) {
                for (std::size_t r = 0; r < chunk->cells.size(); ++r) {
                  Real* cell = sum + chunk->cells[r] * C;
                  const double* run = chunk->sums.data() + r * stride;
                  for (int c = 0; c < C; ++c) cell[c] += static_cast<Real>(run[c]);
                  weight[chunk->cells[r]] += static_cast<Real>(run[C]);
                }
                progress.add(static_cast<std::size_t>(chunk->end_row - chunk->first_row));
                free_chunks.push(chunk);
              }));

  // Normalise by the weight each output texel received (a constant map stays exactly constant). An output texel no
  // square reached (possible only where output texels are smaller than source texels) takes the nearest source
  // texel that is not hot.
  tbb::parallel_for(0, DH, [&](int tj) {
    for (int ti = 0; ti < DW; ++ti) {
      if (dst_omega(ti, tj) <= 0.0) continue;
      const std::size_t t = std::size_t(tj) * DW + ti;
      const Real* value = sum + t * C;
      float* px = out.pixels.data() + t * Co;
      if (weight[t] > Real(0)) {
        for (int c = 0; c < C; ++c) px[c] = static_cast<float>(double(value[c]) / double(weight[t]));
        continue;
      }
      Vec3 d;
      Vec2 q;
      if (!dst.covered_point(ti, tj, q) || !dst.to_direction(q, d)) continue;
      const Vec2 p = sp.to_image(apply(dst_to_src, d));
      const std::size_t index = std::size_t(std::clamp(static_cast<int>(p.y), 0, H - 1)) * W +
                                std::size_t(std::clamp(static_cast<int>(p.x), 0, W - 1));
      if (std::binary_search(hot.begin(), hot.end(), index)) continue;
      for (int c = 0; c < C; ++c) px[c] = img.pixels[index * C + c];
    }
  });
}

}  // namespace

std::vector<ScatterRun> scatter_runs(const MapRef& s, const Parameterization& dst, const Mat3& dst_to_src,
                                     const ResampleOptions& opt, const AreaTables& omega, ScatterKernel kernel) {
  const Image& img = s.image;
  const std::vector<std::size_t> hot = find_hot_texels(img, omega.src, opt.hot_fraction, opt.hot_contrast);
  const ScatterGeometry geometry(s.param, dst, omega.src, omega.dst, dst_to_src);
  const int stride = img.channels + 1;
  std::vector<ScatterRun> runs;
  Chunk chunk;
  for (int first = 0; first < img.height; first += kMaxRowsPerChunk) {
    chunk.start(first, std::min(img.height, first + kMaxRowsPerChunk), stride);
    if (kernel == ScatterKernel::PerTexel)
      project_chunk_per_texel(geometry, img, hot, chunk);
    else
      project_chunk_batched(geometry, img, hot, kernel == ScatterKernel::Batched && use_avx2(), chunk);
    for (std::size_t r = 0; r < chunk.cells.size(); ++r)
      runs.push_back({chunk.cells[r], std::vector<double>(chunk.sums.begin() + std::ptrdiff_t(r * stride),
                                                          chunk.sums.begin() + std::ptrdiff_t((r + 1) * stride))});
  }
  return runs;
}

Image resample_area_scatter(const MapRef& s, const TexelSource& source, const Parameterization& dst,
                            const Mat3& dst_to_src, const ResampleOptions& opt, const AreaTables& omega,
                            ScatterKernel kernel) {
  const Image& img = s.image;
  Image out = make_output(img, dst, output_layout(img, source));
  const SolidAngleTable& src_omega = omega.src;
  const SolidAngleTable& dst_omega = omega.dst;
  const std::vector<std::size_t> hot = find_hot_texels(img, src_omega, opt.hot_fraction, opt.hot_contrast);
  ProgressCounter progress(opt.progress, static_cast<std::size_t>(img.height) + 1);
  const double ratio = double(img.texel_count()) / std::max(1.0, double(dst.width()) * double(dst.height()));
  if (ratio <= kFloatAccumulationMaxRatio)
    scatter_and_normalise<float>(s, dst, src_omega, dst_omega, hot, dst_to_src, kernel, progress, out);
  else
    scatter_and_normalise<double>(s, dst, src_omega, dst_omega, hot, dst_to_src, kernel, progress, out);
  progress.add(1);
  splat_hot_texels(s, hot, src_omega, dst, dst_omega, dst_to_src, out);
  // Each copy of a twin texel received only its own side of the seam or cube edge.
  merge_twin_texels(dst, dst_omega, out);
  return out;
}

}  // namespace envkit::detail
