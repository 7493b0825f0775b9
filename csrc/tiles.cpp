#include "tiles.h"

#include <algorithm>
#include <numeric>

#include "splat_math.h"

namespace edgedog {

TileLists build_tile_lists(int64_t n, const float* means2d, const float* depths, const float* extents,
                           const uint8_t* valid, int width, int height) {
  TileLists lists;
  lists.tiles_x = (width + kTileSize - 1) / kTileSize;
  lists.tiles_y = (height + kTileSize - 1) / kTileSize;
  const int tiles = lists.tiles_x * lists.tiles_y;

  std::vector<splat::TileRect> rects(n);
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < n; ++i)
    rects[i] = splat::tile_rect(means2d + 2 * i, extents + 2 * i, valid[i], width, height);
  lists.offsets.assign(tiles + 1, 0);
  for (int64_t i = 0; i < n; ++i) {
    for (int ty = rects[i].y0; ty <= rects[i].y1; ++ty) {
      for (int tx = rects[i].x0; tx <= rects[i].x1; ++tx) ++lists.offsets[ty * lists.tiles_x + tx + 1];
    }
  }
  std::partial_sum(lists.offsets.begin(), lists.offsets.end(), lists.offsets.begin());
  lists.ids.resize(lists.offsets.back());
  std::vector<int32_t> cursor(lists.offsets.begin(), lists.offsets.end() - 1);
  for (int64_t i = 0; i < n; ++i) {
    for (int ty = rects[i].y0; ty <= rects[i].y1; ++ty) {
      for (int tx = rects[i].x0; tx <= rects[i].x1; ++tx)
        lists.ids[cursor[ty * lists.tiles_x + tx]++] = int32_t(i);
    }
  }
  // Each tile's run, front to back; the index breaks depth ties. Runs are short and independent.
  auto front_to_back = [depths](int32_t a, int32_t b) {
    return depths[a] < depths[b] || (depths[a] == depths[b] && a < b);
  };
#pragma omp parallel for schedule(dynamic, 16)
  for (int k = 0; k < tiles; ++k) {
    std::sort(lists.ids.begin() + lists.offsets[k], lists.ids.begin() + lists.offsets[k + 1], front_to_back);
  }
  return lists;
}

}  // namespace edgedog
