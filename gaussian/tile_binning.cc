// Counting sort of (tile, splat) pairs: splats arrive depth-sorted, so
// filling each tile's list in splat order yields depth-ordered lists without
// a per-tile sort.
#include "gaussian/tile_binning.h"

#include <algorithm>

namespace watergs {

TileRange TilesCoveringRect(int x0, int y0, int width, int height) {
  TileRange r;
  if (width <= 0 || height <= 0) return r;
  r.x0 = x0 / kTileSize;
  r.y0 = y0 / kTileSize;
  r.x1 = (x0 + width + kTileSize - 1) / kTileSize;
  r.y1 = (y0 + height + kTileSize - 1) / kTileSize;
  return r;
}

TileRange Intersect(const TileRange& a, const TileRange& b) {
  TileRange r;
  r.x0 = std::max(a.x0, b.x0);
  r.y0 = std::max(a.y0, b.y0);
  r.x1 = std::max(r.x0, std::min(a.x1, b.x1));
  r.y1 = std::max(r.y0, std::min(a.y1, b.y1));
  return r;
}

void BinSplats(const std::vector<TileRange>& splat_tiles,
               const TileRange& range, TileBins* bins) {
  bins->range = range;
  const int range_w = range.x1 - range.x0;
  const int num_tiles = bins->NumTiles();
  bins->offsets.assign(static_cast<size_t>(num_tiles) + 1, 0);
  std::vector<uint32_t>& offsets = bins->offsets;
  for (const TileRange& t : splat_tiles) {
    for (int ty = t.y0; ty < t.y1; ++ty) {
      uint32_t* row = &offsets[(ty - range.y0) * range_w + 1];
      for (int tx = t.x0; tx < t.x1; ++tx) ++row[tx - range.x0];
    }
  }
  for (int k = 0; k < num_tiles; ++k) offsets[k + 1] += offsets[k];
  bins->ids.resize(offsets[num_tiles]);
  bins->entries.resize(offsets[num_tiles]);
  bins->splat_offsets.resize(splat_tiles.size() + 1);
  bins->splat_offsets[0] = 0;
  std::vector<uint32_t> cursor(offsets.begin(), offsets.end() - 1);
  uint32_t entry = 0;
  for (size_t i = 0; i < splat_tiles.size(); ++i) {
    const TileRange& t = splat_tiles[i];
    for (int ty = t.y0; ty < t.y1; ++ty) {
      uint32_t* row = &cursor[(ty - range.y0) * range_w];
      for (int tx = t.x0; tx < t.x1; ++tx) {
        const uint32_t pos = row[tx - range.x0]++;
        bins->ids[pos] = static_cast<uint32_t>(i);
        bins->entries[entry++] = pos;
      }
    }
    bins->splat_offsets[i + 1] = entry;
  }
}

}  // namespace watergs
