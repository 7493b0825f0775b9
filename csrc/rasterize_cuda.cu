// CUDA kernels of the compositing: one block per 16x16 tile, one thread per pixel, the tile's
// primitives staged in shared memory a block-full at a time (gsplat's layout). Each pixel walks
// its list as the CPU kernel does, through the same functions (splat_math.h); the backward
// passes sum each primitive's per-pixel terms over a warp, then add them to global memory
// with atomics.
#include "cuda_kernels.h"
#include "splat_math.h"

namespace edgedog {
namespace cuda {
namespace {

using splat::Behind;
using splat::PixelHit;
using splat::Tile;

constexpr int kBlock = splat::kTilePixels;  // threads per block: one per pixel of a tile
constexpr unsigned kFullWarp = 0xffffffffu;

// One primitive of the tile's list as the block's threads read it.
struct Staged {
  splat::Footprint fp;
  float depth;
  float color[kMaxChannels];
  int32_t id;
};

__device__ void stage(const Splats& s, int32_t i, const Tile& tile, Staged& out) {
  out.fp = splat::footprint(s, i, tile);
  out.depth = s.depths[i];
  for (int ch = 0; ch < s.channels; ++ch) out.color[ch] = s.colors[int64_t(i) * s.channels + ch];
  out.id = i;
}

// This thread's pixel of the block's tile.
struct Pixel {
  Tile tile;
  int px, py;
  bool inside;  // false for the threads past the right or bottom edge of the image
  int64_t pix;  // row-major index in the image (only meaningful when inside)
};

__device__ Pixel this_pixel(const TileView& tiles, const Frame& f) {
  Pixel p;
  p.tile = splat::tile_at(tiles, blockIdx.x, f);
  const int x = threadIdx.x % kTileSize, y = threadIdx.x / kTileSize;
  p.px = p.tile.x0 + x;
  p.py = p.tile.y0 + y;
  p.inside = x < p.tile.width && y < p.tile.height;
  p.pix = int64_t(p.py) * f.width + p.px;
  return p;
}

__global__ void forward_kernel(Splats s, Frame f, TileView tiles, RasterOutputs out) {
  __shared__ Staged batch[kBlock];
  const Pixel me = this_pixel(tiles, f);
  const int C = s.channels;
  const int begin = tiles.offsets[blockIdx.x], end = tiles.offsets[blockIdx.x + 1];
  float T = 1.f, depth = 0.f, color[kMaxChannels] = {0.f, 0.f, 0.f, 0.f};
  int32_t last = 0;
  bool done = !me.inside;
  for (int start = begin; start < end; start += kBlock) {
    if (__syncthreads_and(done)) break;  // every pixel of the tile is opaque
    if (start + int(threadIdx.x) < end) stage(s, tiles.ids[start + threadIdx.x], me.tile, batch[threadIdx.x]);
    __syncthreads();
    const int count = min(kBlock, end - start);
    for (int j = 0; j < count && !done; ++j) {
      const Staged& p = batch[j];
      PixelHit h;
      if (!p.fp.covers(me.px, me.py) || !splat::hit_pixel(p.fp, me.px, me.py, h)) continue;
      const float next_T = T * (1.f - h.alpha);
      if (next_T < kEarlyStopT) {
        done = true;
        break;
      }
      const float w = h.alpha * T;
      for (int ch = 0; ch < C; ++ch) color[ch] += w * p.color[ch];
      depth += w * p.depth;
      T = next_T;
      last = start + j - begin + 1;
    }
    __syncthreads();  // the batch is read: the next one may overwrite it
  }
  if (!me.inside) return;
  for (int ch = 0; ch < C; ++ch) {
    out.image[me.pix * C + ch] = color[ch] + (f.background ? T * f.background[ch] : 0.f);
  }
  out.alpha[me.pix] = 1.f - T;
  out.depth[me.pix] = depth;
  out.final_T[me.pix] = T;
  out.last[me.pix] = last;
}

__device__ float warp_sum(float v) {
  for (int offset = 16; offset > 0; offset /= 2) v += __shfl_down_sync(kFullWarp, v, offset);
  return v;
}

// Walks the block's tile back to front as the CPU's walk_tile_backwards does, each thread its
// pixel: `visit(p, h, hit, me, T, behind_color, behind)` is called by every thread of the block
// for every position of the list (hit says whether the forward pass composited that primitive
// at this pixel), so that it may reduce over the warp.
template <typename Visit>
__device__ void walk_tile_backwards(const Splats& s, const Frame& f, const TileView& tiles,
                                    const float* final_T, const int32_t* last, Visit& visit) {
  __shared__ Staged batch[kBlock];
  __shared__ int max_used;
  const Pixel me = this_pixel(tiles, f);
  const int begin = tiles.offsets[blockIdx.x];
  float T = me.inside ? final_T[me.pix] : 1.f;
  const int used = me.inside ? last[me.pix] : 0;
  float behind_color[kMaxChannels] = {0.f, 0.f, 0.f, 0.f};
  for (int ch = 0; ch < s.channels; ++ch) behind_color[ch] = f.background ? f.background[ch] : 0.f;
  Behind behind{0.f, 0.f};
  if (threadIdx.x == 0) max_used = 0;
  __syncthreads();
  if (used > 0) atomicMax(&max_used, used);
  __syncthreads();
  for (int hi = max_used; hi > 0; hi -= kBlock) {  // positions [lo, hi), the last first
    const int lo = hi > kBlock ? hi - kBlock : 0;
    if (lo + int(threadIdx.x) < hi)
      stage(s, tiles.ids[begin + lo + threadIdx.x], me.tile, batch[threadIdx.x]);
    __syncthreads();
    for (int pos = hi - 1; pos >= lo; --pos) {
      const Staged& p = batch[pos - lo];
      PixelHit h;
      const bool hit = pos < used && p.fp.covers(me.px, me.py) && splat::hit_pixel(p.fp, me.px, me.py, h);
      if (hit) T /= (1.f - h.alpha);  // transmittance in front of this primitive
      visit(p, h, hit, me, T, behind_color, behind);
      if (hit) behind.absorb(h.alpha, p.color, p.depth, behind_color, s.channels);
    }
    __syncthreads();  // the batch is read: the next one may overwrite it
  }
}

constexpr int kSlots = splat::kColors + kMaxChannels;  // a primitive's gradient slots (splat::GradSlot)

struct GradientVisit {
  Splats s;
  RasterGradOutputs go;
  SplatGrads grads;

  __device__ void operator()(const Staged& p, const PixelHit& h, bool hit, const Pixel& me, float T,
                             const float* behind_color, const Behind& behind) {
    using namespace splat;  // the gradient slots, kMeanX ... kColors
    const int C = s.channels;
    float v[kSlots];
#pragma unroll
    for (int k = 0; k < kSlots; ++k) v[k] = 0.f;
    if (hit) {
      const float w = h.alpha * T;
      const float* g_image = go.image + me.pix * C;
#pragma unroll
      for (int ch = 0; ch < kMaxChannels; ++ch) {
        if (ch < C) v[kColors + ch] = w * g_image[ch];
      }
      v[kDepth] = w * go.depth[me.pix];
      if (!h.clamped) {
        const float g_alpha = splat::alpha_gradient(p.color, p.depth, T, behind_color, behind, g_image,
                                                    go.alpha[me.pix], go.depth[me.pix], C);
        const splat::FootprintGrad fg = splat::footprint_gradient(p.fp, h, g_alpha);
        v[kMeanX] = fg.mean_x;
        v[kMeanY] = fg.mean_y;
        v[kAbsMeanX] = fabsf(fg.mean_x);
        v[kAbsMeanY] = fabsf(fg.mean_y);
        v[kConicA] = fg.conic_a;
        v[kConicB] = fg.conic_b;
        v[kConicC] = fg.conic_c;
        v[kOpacity] = fg.opacity;
        v[kA] = fg.a;
        v[kT] = fg.t;
      }
    }
    if (!__any_sync(kFullWarp, hit)) return;
#pragma unroll
    for (int k = 0; k < kSlots; ++k) v[k] = warp_sum(v[k]);
    if (threadIdx.x % 32 != 0) return;
    const int64_t i = p.id;
    atomicAdd(grads.means2d + 2 * i, v[kMeanX]);
    atomicAdd(grads.means2d + 2 * i + 1, v[kMeanY]);
    atomicAdd(grads.absgrad + 2 * i, v[kAbsMeanX]);
    atomicAdd(grads.absgrad + 2 * i + 1, v[kAbsMeanY]);
    atomicAdd(grads.conics + 3 * i, v[kConicA]);
    atomicAdd(grads.conics + 3 * i + 1, v[kConicB]);
    atomicAdd(grads.conics + 3 * i + 2, v[kConicC]);
    atomicAdd(grads.opacity + i, v[kOpacity]);
    atomicAdd(grads.a + i, v[kA]);
    atomicAdd(grads.t + i, v[kT]);
    atomicAdd(grads.depths + i, v[kDepth]);
#pragma unroll
    for (int ch = 0; ch < kMaxChannels; ++ch) {
      if (ch < C) atomicAdd(grads.colors + i * C + ch, v[kColors + ch]);
    }
  }
};

struct FisherVisit {
  int channels;
  float* fisher;

  __device__ void operator()(const Staged& p, const PixelHit& h, bool hit, const Pixel&, float T,
                             const float* behind_color, const Behind&) {
    // A saturated alpha does not move with D: no information there.
    const bool counts = hit && !h.clamped;
    const float v = counts ? splat::fisher_term(p.color, behind_color, T, p.fp.opacity, channels) : 0.f;
    if (!__any_sync(kFullWarp, counts)) return;
    const float sum = warp_sum(v);
    if (threadIdx.x % 32 == 0) atomicAdd(fisher + p.id, sum);
  }
};

__global__ void backward_kernel(Splats s, Frame f, TileView tiles, const float* final_T, const int32_t* last,
                                RasterGradOutputs go, SplatGrads grads) {
  GradientVisit visit{s, go, grads};
  walk_tile_backwards(s, f, tiles, final_T, last, visit);
}

__global__ void fisher_kernel(Splats s, Frame f, TileView tiles, const float* final_T, const int32_t* last,
                              float* fisher) {
  FisherVisit visit{s.channels, fisher};
  walk_tile_backwards(s, f, tiles, final_T, last, visit);
}

int tile_count(const TileView& tiles) { return tiles.tiles_x * tiles.tiles_y; }

}  // namespace

cudaError_t rasterize_forward(const Splats& s, const Frame& f, const TileView& tiles,
                              const RasterOutputs& out, cudaStream_t stream) {
  forward_kernel<<<tile_count(tiles), kBlock, 0, stream>>>(s, f, tiles, out);
  return cudaGetLastError();
}

cudaError_t rasterize_backward(const Splats& s, const Frame& f, const TileView& tiles, const float* final_T,
                               const int32_t* last, const RasterGradOutputs& go, const SplatGrads& grads,
                               cudaStream_t stream) {
  if (s.n == 0) return cudaSuccess;
  backward_kernel<<<tile_count(tiles), kBlock, 0, stream>>>(s, f, tiles, final_T, last, go, grads);
  return cudaGetLastError();
}

cudaError_t rasterize_fisher(const Splats& s, const Frame& f, const TileView& tiles, const float* final_T,
                             const int32_t* last, float* fisher, cudaStream_t stream) {
  if (s.n == 0) return cudaSuccess;
  fisher_kernel<<<tile_count(tiles), kBlock, 0, stream>>>(s, f, tiles, final_T, last, fisher);
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace edgedog
