#pragma once
// Pieces shared by the resampling algorithms (resample.cpp: point filters and the area gather;
// resample_scatter.cpp: the area scatter). Private to libenv.
#include <envkit/maps/solid_angle_table.h>
#include <envkit/resample/filter.h>
#include <envkit/resample/resample.h>

#include <atomic>
#include <cstddef>
#include <mutex>
#include <utility>
#include <vector>

namespace envkit::detail {

/// Reports progress in steps of about 1% from whichever worker crosses a step.
class ProgressCounter {
 public:
  ProgressCounter(const ProgressFn& fn, std::size_t total) : fn_(fn), total_(total > 0 ? total : 1) {}
  void add(std::size_t n);

 private:
  const ProgressFn& fn_;
  std::size_t total_;
  std::atomic<std::size_t> done_{0};
  std::mutex mutex_;
};

struct OutputLayout {
  int channels = 0;  // output channels
  int alpha = -1;    // output alpha index
  bool add_coverage = false;
};

OutputLayout output_layout(const Image& src, const TexelSource& source);
Image make_output(const Image& src, const Parameterization& dst, const OutputLayout& o);

/// The source texel that covers exactly the region of the sphere output texel (i, j) covers, as an index into the
/// source image, or -1. That is the case where the two grids coincide up to a permutation of whole texels (a
/// shift, quarter turns and flips: rotations by whole texels, convention changes, cube layout changes), and then
/// the exact area average over the output texel is the source texel's value. `centre_pos` is the source position
/// of the output texel's centre: any output texel whose centre is not a source texel centre is rejected at once.
std::ptrdiff_t coincident_source_texel(const Parameterization& src, const Parameterization& dst, const Mat3& dst_to_src,
                                       bool rotate, int i, int j, Vec2 centre_pos);

/// Output texels that take a source texel's value as it is: (output texel, source texel) indices.
using TexelCopies = std::vector<std::pair<std::size_t, std::size_t>>;
/// Writes each copied texel's source value (every channel; coverage 1 where the output adds coverage).
void apply_texel_copies(const Image& src, const TexelCopies& copies, const OutputLayout& o, Image& out);

/// The whole source, texel for texel, for a destination with the same grid under the identity.
Image copy_same_grid(const Image& src, const Parameterization& param, const OutputLayout& o);

/// Texels that are both far brighter than the mean (radiance above `contrast` times power / 4 pi) and carry a real
/// share (above `fraction`) of a channel's power, the power as total_power() gives it (sorted indices).
std::vector<std::size_t> find_hot_texels(const Image& img, const SolidAngleTable& omega, double fraction,
                                         double contrast);

/// Corner-sampled outputs (OpenEXR's lat-long and cube) hold texels twice: a lat-long's first and last columns,
/// and a cube's edge texels, which lie on the cube's edges and corners and belong to two or three faces. Each
/// copy covers only its own side of the texel's cell, so an area filter that integrates per copy gives twins
/// different values (a seam). This gives every twin the solid-angle weighted mean of its copies: the average
/// over the whole cell, total power unchanged. No-op for centre-sampled and other parameterizations.
void merge_twin_texels(const Parameterization& dst, const SolidAngleTable& omega, Image& out);

/// Adds the flux of each hot texel to `out`: the texel is cut into sub-cells with exact solid angles and each
/// sub-cell's flux L x omega goes to the output texel that sees it (divided by that texel's solid angle), so their
/// power is conserved to round-off whatever their size. Deterministic (serial accumulation in a fixed order).
void splat_hot_texels(const MapRef& src, const std::vector<std::size_t>& hot, const SolidAngleTable& src_omega,
                      const Parameterization& dst, const SolidAngleTable& dst_omega, const Mat3& dst_to_src,
                      Image& out);

/// Both maps' exact texel solid angles (a cube's is a per-texel table: 25 MB for faces of 1024), built once per
/// resampling and shared by the choice of the area method and the method itself.
struct AreaTables {
  AreaTables(const Parameterization& src_param, const Parameterization& dst_param) : src(src_param), dst(dst_param) {}
  SolidAngleTable src, dst;
};

/// choose_area_method (resample.h) on tables already built.
AreaMethod choose_area_method(const Parameterization& src, const Parameterization& dst, const TexelSource& source,
                              const AreaTables& omega);

/// The area gather's kernels: both give the same output. PerTexel projects each output texel's centre through the
/// maps' virtual calls and asks of each whether it coincides with a source texel; Batched projects a row of centres
/// at once (lat-long rows into a cube on vector lanes, bit for bit) and asks only where the solid angles agree.
enum class GatherKernel { Batched, PerTexel };

/// The `area` filter's gather (resample.h): each output texel supersampled over its footprint, magnified texels
/// written as the bilinear reconstruction at their centre.
Image resample_area_gather(const MapRef& src, const TexelSource& source, const Parameterization& dst,
                           const Mat3& dst_to_src, const ResampleOptions& opt, const AreaTables& omega,
                           GatherKernel kernel = GatherKernel::Batched);

/// The area scatter's kernels. The first three sum by chunks of source rows and give the same contributions in the
/// same order (so the same output): PerTexel branches on where each texel's square lies; Batched lists a batch of
/// texels' contributions, then adds them, their shares computed on AVX2 lanes where the CPU has them (and
/// ENVKIT_SIMD allows) to the same doubles; BatchedPortable is Batched without the lanes (the tests hold Batched to it
/// bit for bit). OutputOrder sums Batched's shares by tiles of the output (scatter_output_order.cpp): the same shares,
/// summed in another order. Auto: scatter_kernel_for().
enum class ScatterKernel { Auto, Batched, PerTexel, BatchedPortable, OutputOrder };

/// The scatter kernel Auto takes: OutputOrder for a lat-long source into a cube map whose faces the tiles align with
/// (output_tiles_aligned) and that has at most 16 source texels per output texel, Batched for the rest.
ScatterKernel scatter_kernel_for(const Parameterization& src, const Parameterization& dst);

/// Whether OutputOrder's tiles never straddle the output's blocks in which taps resolve to themselves
/// (Parameterization::tap_cell: 0, or a multiple of the tile size): then a texel whose square's cells lie in one tile
/// is settled without resolving them; otherwise every texel is resolved cell by cell (right, but slower).
bool output_tiles_aligned(const Parameterization& dst);

/// One run a scatter kernel hands on: an output texel and, in double, its C flux-weighted channel sums then the weight.
struct ScatterRun {
  std::size_t cell;
  std::vector<double> sums;
};
/// Every run `kernel` gives for the whole source, chunk after chunk of 8 rows, serially: what the tests compare when
/// they hold two kernels to the same doubles (the output, rounded to float, hides differences of an ulp).
std::vector<ScatterRun> scatter_runs(const MapRef& src, const Parameterization& dst, const Mat3& dst_to_src,
                                     const ResampleOptions& opt, const AreaTables& omega, ScatterKernel kernel);

/// The `area` filter's scatter (resample.h): each source texel's flux spread over the output texels that a square of
/// its solid angle, centred on its projection, overlaps. Needs a source with data in every texel.
Image resample_area_scatter(const MapRef& src, const TexelSource& source, const Parameterization& dst,
                            const Mat3& dst_to_src, const ResampleOptions& opt, const AreaTables& omega,
                            ScatterKernel kernel = ScatterKernel::Auto);

/// The scatter's shares summed by tiles of the output (ScatterKernel::OutputOrder) and normalised into `out` (each
/// output texel's weighted mean; the nearest source texel where no square reached), hot texels with weight only.
void scatter_in_output_order(const MapRef& s, const Parameterization& dst, const SolidAngleTable& src_omega,
                             const SolidAngleTable& dst_omega, const std::vector<std::size_t>& hot,
                             const Mat3& dst_to_src, bool lanes, ProgressCounter& progress, Image& out);

}  // namespace envkit::detail
