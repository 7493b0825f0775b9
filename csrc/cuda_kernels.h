// The CUDA kernels' launchers, over device pointers (no torch headers: csrc/bindings.cpp
// allocates, checks and calls them on torch's current stream). Each returns the launch's
// error. The maths is the CPU kernels', shared through project_math.h and splat_math.h.
#pragma once

#include <cuda_runtime_api.h>

#include <cstdint>

#include "project.h"
#include "rasterize.h"
#include "tiles.h"

namespace edgedog {
namespace cuda {

constexpr int kMaxChannels = 4;  // colour channels a pixel thread keeps in registers

cudaError_t project_forward(const PinholeCamera& cam, const ProjectInputs& in, const ProjectOutputs& out,
                            cudaStream_t stream);
cudaError_t project_backward(const PinholeCamera& cam, const ProjectInputs& in, const ProjectGradOutputs& go,
                             const ProjectGradInputs& gi, cudaStream_t stream);

// Tile lists in two passes around a sort (done by the caller): `tile_counts` writes how many
// tiles each primitive touches (n,); given their inclusive prefix sums `ends`, `tile_keys` writes
// one (key, primitive) pair per touched tile, key = tile << 32 | depth's order bits, in
// primitive order, so that a stable sort by key gives each tile's run front to back with the
// index breaking depth ties (as the CPU's lists).
cudaError_t tile_counts(int64_t n, const float* means2d, const float* extents, const uint8_t* valid,
                        int width, int height, int64_t* counts, cudaStream_t stream);
cudaError_t tile_keys(int64_t n, const float* means2d, const float* depths, const float* extents,
                      const uint8_t* valid, int width, int height, const int64_t* ends, int64_t* keys,
                      int32_t* values, cudaStream_t stream);

// As the CPU functions of rasterize.h; `grads` and `fisher` must be zeroed (they are summed
// into with atomics, so their last bits vary from run to run).
cudaError_t rasterize_forward(const Splats& s, const Frame& f, const TileView& tiles,
                              const RasterOutputs& out, cudaStream_t stream);
cudaError_t rasterize_backward(const Splats& s, const Frame& f, const TileView& tiles, const float* final_T,
                               const int32_t* last, const RasterGradOutputs& go, const SplatGrads& grads,
                               cudaStream_t stream);
cudaError_t rasterize_fisher(const Splats& s, const Frame& f, const TileView& tiles, const float* final_T,
                             const int32_t* last, float* fisher, cudaStream_t stream);

}  // namespace cuda
}  // namespace edgedog
