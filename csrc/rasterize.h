// Tile-based front-to-back compositing of DoG (or Gaussian) splats, forward, backward and
// Fisher sensitivity. Mirrors renderer/_torch_ref.py: rasterize() and composite().
#pragma once

#include <cstdint>

#include "tiles.h"

namespace edgedog {

// Per-primitive screen-space inputs, all contiguous float32, in the order every binding and
// Python wrapper takes them: the projection's outputs, the activated parameters, the colours.
struct Splats {
  int64_t n;
  int channels;
  const float* means2d;  // (n, 2)
  const float* conics;   // (n, 3)
  const float* depths;   // (n,)
  const float* extents;  // (n, 2) half-widths in pixels of the support ellipse
  const float* opacity;  // (n,) in (0, 1)
  const float* a;        // (n,) inner scale of the footprint: u = q / (2a)
  const float* t;        // (n,) DoG ratio in [0, 1); 0 is the plain Gaussian
  const float* support;  // (n,) largest u that can reach the minimum alpha
  const float* colors;   // (n, channels)
};

struct Frame {
  int width, height;
  const float* background;  // (channels,) or nullptr for black
};

struct RasterOutputs {
  float* image;    // (H, W, C)
  float* alpha;    // (H, W)
  float* depth;    // (H, W)  sum z_i alpha_i T_i
  float* final_T;  // (H, W)  transmittance after the last primitive, for the backward pass
  int32_t* last;   // (H, W)  1 + position in the tile list of the last primitive used
};

struct RasterGradOutputs {  // dL/d(image, alpha, depth)
  const float* image;
  const float* alpha;
  const float* depth;
};

struct SplatGrads {  // dL/d(inputs), written (not accumulated)
  float* means2d;
  float* conics;
  float* depths;
  float* opacity;
  float* a;
  float* t;
  float* colors;
  float* absgrad;  // (N, 2) sum over pixels of |per-pixel dL/dmean2d| (gsplat's absgrad)
};

void rasterize_forward(const Splats& s, const Frame& f, const TileView& tiles, const RasterOutputs& out);

void rasterize_backward(const Splats& s, const Frame& f, const TileView& tiles, const float* final_T,
                        const int32_t* last, const RasterGradOutputs& grad_out, const SplatGrads& grads);

// Adds to fisher[i] the sum over pixels and channels of (dI_c / dD_i)^2, D_i the primitive's
// footprint response at the pixel (the paper's U_i for one view).
void rasterize_fisher(const Splats& s, const Frame& f, const TileView& tiles, const float* final_T,
                      const int32_t* last, float* fisher);

}  // namespace edgedog
