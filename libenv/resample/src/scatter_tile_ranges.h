#pragma once
// Which source texels can reach each tile of the output (the area scatter summed by tiles, scatter_output_order.cpp):
// per tile, one range of columns per source row. Private to libenv's resample group.
#include <cstddef>
#include <vector>

#include "scatter_shares.h"

namespace envkit::detail {

/// Tiles of kTile x kTile output texels: their accumulators (C + 1 doubles per texel, 128 KB for RGB) stay in L2.
/// output_tiles_aligned (resample_common.h) says whether they align with the output's blocks.
constexpr int kTileBits = 6;
constexpr int kTile = 1 << kTileBits;

/// Source texels [start, start + count) of a row (columns taken modulo the row's width).
struct ColumnRange {
  int row, start, count;
};

/// Each tile's source texels: tile t (tiles_x to a row of tiles, row-major over the output image) has
/// ranges[first[t]] to ranges[first[t + 1] - 1], in source row order.
struct TileRanges {
  int tiles_x = 0, tiles = 0;
  std::vector<std::size_t> first;
  std::vector<ColumnRange> ranges;
};

/// The ranges of every tile of g's output: a texel lies in tile t's range on its row whenever one of its shares'
/// resolved cells lies in t (a superset: texels near t's edges can be in a range with no share in t). Rows are
/// scanned in parallel, each by itself, so the result does not depend on the thread count. `lanes`: the codes on AVX2
/// lanes (use_avx2()).
TileRanges tile_ranges(const ScatterGeometry& g, bool lanes);

}  // namespace envkit::detail
