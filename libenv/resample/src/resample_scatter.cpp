// The `area` filter's scatter (see resample.h): for shrinking, each source texel is read once and its flux is
// spread over the output texels that a square of its solid angle, centred on its projection, overlaps.
#include <envkit/core/huge_page_allocator.h>
#include <envkit/core/simd/simd_level.h>
#include <tbb/blocked_range.h>
#include <tbb/concurrent_queue.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <type_traits>

#include "resample_common.h"
#include "scatter_shares.h"

namespace envkit::detail {

namespace {

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
/// Source texels per output texel (on average) up to which summing by output tiles is chosen (scatter_kernel_for).
constexpr double kOutputOrderMaxRatio = 16.0;

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
  std::vector<std::size_t> cells;       // output texel of each run
  std::vector<double> sums;             // per run: C flux-weighted channel sums, then the weight
  std::vector<std::size_t> slot_cell;   // output texel held by each slot, kEmpty when none
  std::vector<double> slot_sums;        // per slot: as sums
  std::vector<float> hot_pixels;        // the batched kernel's copies of hot texels, colour zeroed
  std::unique_ptr<ShareLister> lister;  // the batched kernel's lists of shares
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

/// The batched kernel: the same contributions as project_chunk_per_texel, in the same order (ShareLister lists them a
/// batch of texels at a time), then added to the chunk's slots. Hot texels point at a copy of their channels with zero
/// colour. With `lanes` (and an output whose texels are close to square), the shares of a batch are computed on vector
/// lanes first, to the same doubles.
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
  chunk.hot_pixels =
      hot_weight_copies(img, hot.data() + (hot_begin - hot.begin()), hot.data() + (hot_end - hot.begin()));
  if (!chunk.lister) chunk.lister = std::make_unique<ShareLister>(g, lanes);
  HotCursor cursor{hot.data() + (hot_begin - hot.begin()), hot.data() + (hot_end - hot.begin()),
                   chunk.hot_pixels.data(), C};
  for (int j = chunk.first_row; j < chunk.end_row; ++j) chunk.lister->texels(img, j, 0, W, cursor, add);
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
      nearest_source_texel(s, dst, dst_to_src, hot, ti, tj, px);
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

ScatterKernel scatter_kernel_for(const Parameterization& src, const Parameterization& dst) {
  // Tiles project each source texel twice (once to find the tiles it reaches): cheap only where lat-long rows are
  // projected into a cube on vector lanes; into a lat-long, octahedral or HEALPix output the second projection cost
  // more than the accumulator saved (8k .hdr -> lat-long 2048 +39% CPU, octahedral 2048 +11%, HEALPix 512 +52%). And
  // the chunks' slots hold a small output well: tiles gained 15-20% CPU at 5 source texels per output texel (4k ->
  // cube 512; 8k -> 1024: 10%), nothing at 21 (8k -> 512, 4k -> 256) and lost 8% at 85 (8k -> 256).
  const bool rows_on_lanes = src.kind() == Kind::LatLong && dst.kind() == Kind::CubeMap;
  const double ratio = double(src.width()) * double(src.height()) / std::max(1.0, double(dst.width()) * dst.height());
  return rows_on_lanes && output_tiles_aligned(dst) && ratio <= kOutputOrderMaxRatio ? ScatterKernel::OutputOrder
                                                                                     : ScatterKernel::Batched;
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
  if (kernel == ScatterKernel::Auto) kernel = scatter_kernel_for(s.param, dst);
  if (kernel == ScatterKernel::OutputOrder)
    scatter_in_output_order(s, dst, src_omega, dst_omega, hot, dst_to_src, use_avx2(), progress, out);
  else if (ratio <= kFloatAccumulationMaxRatio)
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