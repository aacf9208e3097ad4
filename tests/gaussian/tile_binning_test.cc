// Tile binning against a brute-force listing.
#include "gaussian/tile_binning.h"

#include <gtest/gtest.h>

#include <random>

namespace watergs {
namespace {

TEST(TileBinning, ListsMatchBruteForceInSplatOrder) {
  std::mt19937 rng(2);
  std::uniform_int_distribution<int> tx(0, 9), ty(0, 6), span(0, 3);
  const TileRange range{1, 2, 8, 7};
  std::vector<TileRange> splats(500);
  for (TileRange& t : splats) {
    t.x0 = tx(rng), t.y0 = ty(rng);
    t.x1 = t.x0 + span(rng), t.y1 = t.y0 + span(rng);
    t = Intersect(t, range);
  }
  TileBins bins;
  BinSplats(splats, range, &bins);
  ASSERT_EQ(bins.NumTiles(), 35);
  size_t total = 0;
  for (int y = range.y0; y < range.y1; ++y) {
    for (int x = range.x0; x < range.x1; ++x) {
      std::vector<uint32_t> want;
      for (size_t i = 0; i < splats.size(); ++i) {
        const TileRange& t = splats[i];
        if (x >= t.x0 && x < t.x1 && y >= t.y0 && y < t.y1) want.push_back(i);
      }
      const int k = (y - range.y0) * 7 + (x - range.x0);
      const std::vector<uint32_t> got(bins.ids.begin() + bins.offsets[k],
                                      bins.ids.begin() + bins.offsets[k + 1]);
      EXPECT_EQ(got, want) << x << "," << y;
      total += want.size();
    }
  }
  EXPECT_EQ(bins.ids.size(), total);
  EXPECT_GT(total, 100u);
  // The splat-major index visits every entry once, each splat's in tile order.
  ASSERT_EQ(bins.splat_offsets.size(), splats.size() + 1);
  std::vector<int> seen(bins.ids.size(), 0);
  for (size_t i = 0; i < splats.size(); ++i) {
    const TileRange& t = splats[i];
    const int area = t.empty() ? 0 : (t.x1 - t.x0) * (t.y1 - t.y0);
    ASSERT_EQ(bins.splat_offsets[i + 1] - bins.splat_offsets[i], area);
    for (uint32_t e = bins.splat_offsets[i]; e < bins.splat_offsets[i + 1];
         ++e) {
      EXPECT_EQ(bins.ids[bins.entries[e]], i);
      if (e > bins.splat_offsets[i]) {
        EXPECT_GT(bins.entries[e], bins.entries[e - 1]);
      }
      ++seen[bins.entries[e]];
    }
  }
  for (int count : seen) EXPECT_EQ(count, 1);
}

TEST(TileBinning, TilesCoveringRect) {
  const TileRange r = TilesCoveringRect(15, 16, 2, 17);
  EXPECT_EQ(r.x0, 0);
  EXPECT_EQ(r.x1, 2);
  EXPECT_EQ(r.y0, 1);
  EXPECT_EQ(r.y1, 3);
  EXPECT_TRUE(TilesCoveringRect(0, 0, 0, 5).empty());
  EXPECT_TRUE(Intersect(TileRange{0, 0, 2, 2}, TileRange{2, 0, 4, 2}).empty());
}

}  // namespace
}  // namespace watergs
