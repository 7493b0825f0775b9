#include "rasterize.h"

#include <algorithm>
#include <vector>

#include "parallel.h"
#include "splat_math.h"

namespace edgedog {
namespace {

using splat::Behind;
using splat::Footprint;
using splat::kTilePixels;
using splat::PixelHit;
using splat::Tile;

// Per-thread gradient buffers, reduced at the end: tiles touch primitives in any order.
struct ThreadBuffers {
  int threads;
  int64_t stride;
  std::vector<float> data;
  ThreadBuffers(int threads, int64_t n, int64_t per_primitive)
      : threads(threads), stride(n * per_primitive), data(size_t(threads) * n * per_primitive, 0.f) {}
  float* of(int thread) { return data.data() + thread * stride; }
  // Sums every thread's buffer into the first one and returns it.
  const float* reduce() {
    float* first = of(0);
#pragma omp parallel for schedule(static)
    for (int64_t k = 0; k < stride; ++k) {
      for (int th = 1; th < threads; ++th) first[k] += of(th)[k];
    }
    return first;
  }
};

// Every pixel as an empty tile leaves it: nothing composited, the background showing. One pass
// over whole buffers (long contiguous runs) before the tiles: most tiles of an edge render are
// empty, and filling them row by row costs a library call per 16 pixels.
void write_background(const Frame& f, int C, const RasterOutputs& out) {
#pragma omp parallel for schedule(static)
  for (int y = 0; y < f.height; ++y) {
    const int64_t row = int64_t(y) * f.width;
    std::fill(out.alpha + row, out.alpha + row + f.width, 0.f);
    std::fill(out.depth + row, out.depth + row + f.width, 0.f);
    std::fill(out.final_T + row, out.final_T + row + f.width, 1.f);
    std::fill(out.last + row, out.last + row + f.width, 0);
    if (f.background == nullptr) {
      std::fill(out.image + row * C, out.image + (row + f.width) * C, 0.f);
    } else {
      for (int x = 0; x < f.width; ++x) std::copy(f.background, f.background + C, out.image + (row + x) * C);
    }
  }
}

}  // namespace

void rasterize_forward(const Splats& s, const Frame& f, const TileView& tiles, const RasterOutputs& out) {
  const int num_tiles = tiles.tiles_x * tiles.tiles_y;
  const int C = s.channels;
  write_background(f, C, out);
#pragma omp parallel
  {
    std::vector<float> T(kTilePixels), color(kTilePixels * C), depth(kTilePixels);
    std::vector<int32_t> last(kTilePixels);
    std::vector<uint8_t> done(kTilePixels);
#pragma omp for schedule(dynamic, 4)
    for (int index = 0; index < num_tiles; ++index) {
      const Tile tile = splat::tile_at(tiles, index, f);
      const int begin = tiles.offsets[index], end = tiles.offsets[index + 1];
      if (begin == end) continue;  // left as `write_background` wrote it
      std::fill(T.begin(), T.end(), 1.f);
      std::fill(color.begin(), color.end(), 0.f);
      std::fill(depth.begin(), depth.end(), 0.f);
      std::fill(last.begin(), last.end(), 0);
      std::fill(done.begin(), done.end(), 0);
      int active = tile.width * tile.height;
      for (int k = begin; k < end && active > 0; ++k) {
        const int32_t i = tiles.ids[k];
        const Footprint fp = splat::footprint(s, i, tile);
        const float* c = s.colors + int64_t(i) * C;
        for (int py = fp.y0; py <= fp.y1; ++py) {
          for (int px = fp.x0; px <= fp.x1; ++px) {
            const int p = (py - tile.y0) * kTileSize + (px - tile.x0);
            PixelHit h;
            if (done[p] || !splat::hit_pixel(fp, px, py, h)) continue;
            const float next_T = T[p] * (1.f - h.alpha);
            if (next_T < kEarlyStopT) {
              done[p] = 1;
              --active;
              continue;
            }
            const float w = h.alpha * T[p];
            for (int ch = 0; ch < C; ++ch) color[p * C + ch] += w * c[ch];
            depth[p] += w * s.depths[i];
            T[p] = next_T;
            last[p] = k - begin + 1;
          }
        }
      }
      for (int y = 0; y < tile.height; ++y) {
        for (int x = 0; x < tile.width; ++x) {
          const int p = y * kTileSize + x;
          const int64_t pix = int64_t(tile.y0 + y) * f.width + tile.x0 + x;
          for (int ch = 0; ch < C; ++ch) {
            out.image[pix * C + ch] = color[p * C + ch] + (f.background ? T[p] * f.background[ch] : 0.f);
          }
          out.alpha[pix] = 1.f - T[p];
          out.depth[pix] = depth[p];
          out.final_T[pix] = T[p];
          out.last[pix] = last[p];
        }
      }
    }
  }
}

namespace {

// Walks one tile back to front, recovering each pixel's transmittance before every primitive
// it used and the colour, depth and alpha composited behind it. `visit(i, fp, h, pix, T,
// behind_color, behind)` sees each (primitive, pixel) that the forward pass composited, before
// the "behind" accumulators absorb that primitive.
template <typename Visit>
void walk_tile_backwards(const Splats& s, const Frame& f, const TileView& tiles, int index,
                         const float* final_T, const int32_t* last, Visit&& visit) {
  const int C = s.channels;
  const int begin = tiles.offsets[index];
  if (begin == tiles.offsets[index + 1]) return;  // nothing was composited here
  const Tile tile = splat::tile_at(tiles, index, f);
  float T[kTilePixels];
  Behind behind[kTilePixels];
  int32_t used[kTilePixels];
  std::vector<float> behind_color(kTilePixels * C);
  int max_used = 0;
  for (int y = 0; y < tile.height; ++y) {
    for (int x = 0; x < tile.width; ++x) {
      const int p = y * kTileSize + x;
      const int64_t pix = int64_t(tile.y0 + y) * f.width + tile.x0 + x;
      T[p] = final_T[pix];
      used[p] = last[pix];
      max_used = std::max(max_used, used[p]);
      behind[p] = {0.f, 0.f};
      for (int ch = 0; ch < C; ++ch) behind_color[p * C + ch] = f.background ? f.background[ch] : 0.f;
    }
  }
  for (int pos = max_used - 1; pos >= 0; --pos) {
    const int32_t i = tiles.ids[begin + pos];
    const Footprint fp = splat::footprint(s, i, tile);
    const float* c = s.colors + int64_t(i) * C;
    for (int py = fp.y0; py <= fp.y1; ++py) {
      for (int px = fp.x0; px <= fp.x1; ++px) {
        const int p = (py - tile.y0) * kTileSize + (px - tile.x0);
        PixelHit h;
        if (pos >= used[p] || !splat::hit_pixel(fp, px, py, h)) continue;
        T[p] /= (1.f - h.alpha);  // transmittance in front of this primitive
        const int64_t pix = int64_t(py) * f.width + px;
        visit(i, fp, h, pix, T[p], &behind_color[p * C], behind[p]);
        behind[p].absorb(h.alpha, c, s.depths[i], &behind_color[p * C], C);
      }
    }
  }
}

}  // namespace

void rasterize_backward(const Splats& s, const Frame& f, const TileView& tiles, const float* final_T,
                        const int32_t* last, const RasterGradOutputs& go, const SplatGrads& grads) {
  using namespace splat;  // the gradient slots, kMeanX ... kColors
  const int num_tiles = tiles.tiles_x * tiles.tiles_y;
  const int C = s.channels;
  const int64_t per = kColors + C;
  ThreadBuffers buffers(max_threads(), s.n, per);
#pragma omp parallel
  {
    float* g = buffers.of(thread_index());
#pragma omp for schedule(static, 4)  // fixed tile-to-thread map: reproducible sums
    for (int index = 0; index < num_tiles; ++index) {
      walk_tile_backwards(s, f, tiles, index, final_T, last,
                          [&](int32_t i, const Footprint& fp, const PixelHit& h, int64_t pix, float T,
                              const float* behind_color, const Behind& behind) {
                            float* gi = g + int64_t(i) * per;
                            const float w = h.alpha * T;
                            const float* c = s.colors + int64_t(i) * C;
                            const float* g_image = go.image + pix * C;
                            for (int ch = 0; ch < C; ++ch) gi[kColors + ch] += w * g_image[ch];
                            gi[kDepth] += w * go.depth[pix];
                            if (h.clamped) return;
                            const float g_alpha =
                                splat::alpha_gradient(c, s.depths[i], T, behind_color, behind, g_image,
                                                      go.alpha[pix], go.depth[pix], C);
                            const splat::FootprintGrad fg = splat::footprint_gradient(fp, h, g_alpha);
                            gi[kOpacity] += fg.opacity;
                            gi[kT] += fg.t;
                            gi[kA] += fg.a;
                            gi[kConicA] += fg.conic_a;
                            gi[kConicB] += fg.conic_b;
                            gi[kConicC] += fg.conic_c;
                            gi[kMeanX] += fg.mean_x;
                            gi[kMeanY] += fg.mean_y;
                            gi[kAbsMeanX] += std::fabs(fg.mean_x);
                            gi[kAbsMeanY] += std::fabs(fg.mean_y);
                          });
    }
  }
  const float* acc = buffers.reduce();
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < s.n; ++i) {
    const float* a = acc + i * per;
    grads.means2d[2 * i] = a[kMeanX];
    grads.means2d[2 * i + 1] = a[kMeanY];
    grads.absgrad[2 * i] = a[kAbsMeanX];
    grads.absgrad[2 * i + 1] = a[kAbsMeanY];
    grads.conics[3 * i] = a[kConicA];
    grads.conics[3 * i + 1] = a[kConicB];
    grads.conics[3 * i + 2] = a[kConicC];
    grads.opacity[i] = a[kOpacity];
    grads.a[i] = a[kA];
    grads.t[i] = a[kT];
    grads.depths[i] = a[kDepth];
    for (int ch = 0; ch < C; ++ch) grads.colors[i * C + ch] = a[kColors + ch];
  }
}

void rasterize_fisher(const Splats& s, const Frame& f, const TileView& tiles, const float* final_T,
                      const int32_t* last, float* fisher) {
  const int num_tiles = tiles.tiles_x * tiles.tiles_y;
  const int C = s.channels;
  ThreadBuffers buffers(max_threads(), s.n, 1);
#pragma omp parallel
  {
    float* g = buffers.of(thread_index());
#pragma omp for schedule(static, 4)  // fixed tile-to-thread map: reproducible sums
    for (int index = 0; index < num_tiles; ++index) {
      walk_tile_backwards(s, f, tiles, index, final_T, last,
                          [&](int32_t i, const Footprint& fp, const PixelHit& h, int64_t, float T,
                              const float* behind_color, const Behind&) {
                            if (h.clamped) return;  // alpha saturated: the image does not move with D here
                            g[i] +=
                                splat::fisher_term(s.colors + int64_t(i) * C, behind_color, T, fp.opacity, C);
                          });
    }
  }
  const float* acc = buffers.reduce();
  for (int64_t i = 0; i < s.n; ++i) fisher[i] += acc[i];
}

}  // namespace edgedog
