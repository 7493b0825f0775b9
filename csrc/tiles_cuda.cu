// CUDA kernels of the tile lists' two passes (the sort between them is torch's, in bindings.cpp).
#include "cuda_kernels.h"
#include "splat_math.h"

namespace edgedog {
namespace cuda {
namespace {

constexpr int kThreads = 256;

int blocks_for(int64_t n) { return int((n + kThreads - 1) / kThreads); }

__device__ int64_t rect_size(const splat::TileRect& r) {
  return r.x0 > r.x1 ? 0 : int64_t(r.x1 - r.x0 + 1) * (r.y1 - r.y0 + 1);
}

// Depth's bits, as an unsigned integer with the floats' order (negative depths included).
__device__ uint32_t order_bits(float depth) {
  const uint32_t bits = __float_as_uint(depth);
  return (bits & 0x80000000u) ? ~bits : bits | 0x80000000u;
}

__global__ void tile_counts_kernel(int64_t n, const float* means2d, const float* extents,
                                   const uint8_t* valid, int width, int height, int64_t* counts) {
  const int64_t i = int64_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= n) return;
  counts[i] = rect_size(splat::tile_rect(means2d + 2 * i, extents + 2 * i, valid[i], width, height));
}

__global__ void tile_keys_kernel(int64_t n, const float* means2d, const float* depths, const float* extents,
                                 const uint8_t* valid, int width, int height, const int64_t* ends,
                                 int64_t* keys, int32_t* values) {
  const int64_t i = int64_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const splat::TileRect r = splat::tile_rect(means2d + 2 * i, extents + 2 * i, valid[i], width, height);
  int64_t slot = ends[i] - rect_size(r);
  const int tiles_x = (width + kTileSize - 1) / kTileSize;
  const int64_t depth_bits = order_bits(depths[i]);
  for (int ty = r.y0; ty <= r.y1; ++ty) {
    for (int tx = r.x0; tx <= r.x1; ++tx, ++slot) {
      keys[slot] = (int64_t(ty * tiles_x + tx) << 32) | depth_bits;
      values[slot] = int32_t(i);
    }
  }
}

}  // namespace

cudaError_t tile_counts(int64_t n, const float* means2d, const float* extents, const uint8_t* valid,
                        int width, int height, int64_t* counts, cudaStream_t stream) {
  if (n == 0) return cudaSuccess;
  tile_counts_kernel<<<blocks_for(n), kThreads, 0, stream>>>(n, means2d, extents, valid, width, height,
                                                             counts);
  return cudaGetLastError();
}

cudaError_t tile_keys(int64_t n, const float* means2d, const float* depths, const float* extents,
                      const uint8_t* valid, int width, int height, const int64_t* ends, int64_t* keys,
                      int32_t* values, cudaStream_t stream) {
  if (n == 0) return cudaSuccess;
  tile_keys_kernel<<<blocks_for(n), kThreads, 0, stream>>>(n, means2d, depths, extents, valid, width, height,
                                                           ends, keys, values);
  return cudaGetLastError();
}

}  // namespace cuda
}  // namespace edgedog
