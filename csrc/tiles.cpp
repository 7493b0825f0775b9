#include "tiles.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

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

TileLists build_tile_lists(int64_t n, const float* means2d, const float* extents,
                           const float* depths, const uint8_t* valid, int width, int height) {
  TileLists lists;
  lists.tiles_x = (width + kTileSize - 1) / kTileSize;
  lists.tiles_y = (height + kTileSize - 1) / kTileSize;
  const int tiles = lists.tiles_x * lists.tiles_y;

  // Sort (depth, index) pairs: contiguous keys sort fast, and the index breaks ties.
  std::vector<std::pair<float, int32_t>> keyed;
  keyed.reserve(n);
  for (int64_t i = 0; i < n; ++i) {
    if (valid[i] && extents[2 * i] > 0 && extents[2 * i + 1] > 0) keyed.emplace_back(depths[i], int32_t(i));
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int32_t> order(keyed.size());
  for (size_t k = 0; k < keyed.size(); ++k) order[k] = keyed[k].second;

  std::vector<TileRect> rects(order.size());
  lists.offsets.assign(tiles + 1, 0);
  for (size_t k = 0; k < order.size(); ++k) {
    const int32_t i = order[k];
    rects[k] = tile_rect(means2d + 2 * i, extents + 2 * i, width, height);
    for (int ty = rects[k].y0; ty <= rects[k].y1; ++ty) {
      for (int tx = rects[k].x0; tx <= rects[k].x1; ++tx) ++lists.offsets[ty * lists.tiles_x + tx + 1];
    }
  }
  std::partial_sum(lists.offsets.begin(), lists.offsets.end(), lists.offsets.begin());
  lists.ids.resize(lists.offsets.back());
  std::vector<int32_t> cursor(lists.offsets.begin(), lists.offsets.end() - 1);
  for (size_t k = 0; k < order.size(); ++k) {  // in depth order: each run comes out sorted
    for (int ty = rects[k].y0; ty <= rects[k].y1; ++ty) {
      for (int tx = rects[k].x0; tx <= rects[k].x1; ++tx) lists.ids[cursor[ty * lists.tiles_x + tx]++] = order[k];
    }
  }
  return lists;
}

}  // namespace edgedog
