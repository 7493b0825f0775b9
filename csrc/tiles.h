// Which primitives touch which 16x16 tile, front to back (no gradients).
// Mirrors renderer/_torch_ref.py: tile_lists().
#pragma once

#include <cstdint>
#include <vector>

namespace edgedog {

// Read-only view of the lists, wherever they are stored.
struct TileView {
  int tiles_x, tiles_y;
  const int32_t* offsets;  // (tiles + 1,) tile k owns ids[offsets[k] : offsets[k + 1]]
  const int32_t* ids;      // primitive indices, each tile's run sorted by depth
};

struct TileLists {
  int tiles_x = 0, tiles_y = 0;
  std::vector<int32_t> offsets;
  std::vector<int32_t> ids;
  TileView view() const { return {tiles_x, tiles_y, offsets.data(), ids.data()}; }
};

// A primitive covers the pixel centres x in [m - e, m + e] (and likewise in y); culled ones
// have valid = 0 or a zero extent. Depth ties keep index order.
TileLists build_tile_lists(int64_t n, const float* means2d, const float* depths, const float* extents,
                           const uint8_t* valid, int width, int height);

}  // namespace edgedog
