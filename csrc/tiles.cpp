#include "tiles.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "constants.h"

namespace edgedog {
namespace {

struct TileRect {
  int x0, x1, y0, y1;  // inclusive tile ranges; empty when x0 > x1
};

TileRect tile_rect(const float* m, const float* e, int width, int height) {
  // Pixel centres inside [m - e, m + e], clipped to the image, computed in float before any
  // integer conversion so that huge or NaN coordinates cannot overflow.
  const float px0 = std::max(std::ceil(m[0] - e[0]), 0.f);
  const float px1 = std::min(std::floor(m[0] + e[0]), float(width - 1));
  const float py0 = std::max(std::ceil(m[1] - e[1]), 0.f);
  const float py1 = std::min(std::floor(m[1] + e[1]), float(height - 1));
  if (!(px0 <= px1 && py0 <= py1)) return {1, 0, 1, 0};
  return {int(px0) / kTileSize, int(px1) / kTileSize, int(py0) / kTileSize, int(py1) / kTileSize};
}

}  // namespace

TileLists build_tile_lists(int64_t n, const float* means2d, const float* depths, const float* extents,
                           const uint8_t* valid, int width, int height) {
  TileLists lists;
  lists.tiles_x = (width + kTileSize - 1) / kTileSize;
  lists.tiles_y = (height + kTileSize - 1) / kTileSize;
  const int tiles = lists.tiles_x * lists.tiles_y;

  std::vector<TileRect> rects(n);
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < n; ++i) {
    const bool usable = valid[i] && extents[2 * i] > 0 && extents[2 * i + 1] > 0;
    rects[i] = usable ? tile_rect(means2d + 2 * i, extents + 2 * i, width, height) : TileRect{1, 0, 1, 0};
  }
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
