// Tile binning: per 16 x 16 tile, the list of splats that may touch it, in
// front-to-back order. Only tiles inside the requested tile range are
// binned, so a crop render costs in proportion to the crop.
#pragma once

#include <cstdint>
#include <vector>

#include "gaussian/projection.h"

namespace watergs {

// Per-tile lists over a range of the full frame's tile grid.
struct TileBins {
  // The binned tiles (full-frame tile coordinates).
  TileRange range;
  // Tile (tx, ty) of the range has list ids[offsets[k]..offsets[k+1]) with
  // k = (ty - range.y0) * range width + (tx - range.x0).
  std::vector<uint32_t> offsets;
  // Splat indexes, increasing within a list (splats are depth-sorted).
  std::vector<uint32_t> ids;
  // Splat-major view of the same lists: splat i sits at positions
  // entries[splat_offsets[i]..splat_offsets[i+1]) of `ids`, in tile order
  // (the backward pass sums per-entry gradients in this fixed order).
  std::vector<uint32_t> splat_offsets, entries;
  // Number of tiles in the range.
  int NumTiles() const { return (range.x1 - range.x0) * (range.y1 - range.y0); }
};

// Bins splats 0..n-1, already sorted front to back, whose tile ranges are
// `splat_tiles[i]` (already clipped to `range`). A counting sort on the tile
// key that keeps the depth order inside each tile.
void BinSplats(const std::vector<TileRange>& splat_tiles,
               const TileRange& range, TileBins* bins);

// Tiles of the full frame's grid that cover pixel rectangle
// [x0, x0 + width) x [y0, y0 + height).
TileRange TilesCoveringRect(int x0, int y0, int width, int height);

// Intersection of two tile ranges (may be empty).
TileRange Intersect(const TileRange& a, const TileRange& b);

}  // namespace watergs
