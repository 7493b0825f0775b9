// The projection loss of a training step in three passes over the pixels: EdgeDoG's pixel-level
// uncertainty Up (the Sobel magnitude of the rendered depth, min-max normalised), its weight
// w(Up), and the weighted L1 between the render and the edge map with its gradient. Mirrors
// edgedog/train/losses.py: depth_uncertainty(), uncertainty_weight() and projection_loss(),
// which torch computes in about ten passes over the image.
#pragma once

#include <cstdint>

namespace edgedog {

// w(Up), in the order of losses.WEIGHTINGS: 1, exp(-Up), 1 - Up, Up, exp(Up).
enum class Weighting : int { kOne = 0, kExpNeg = 1, kOneMinus = 2, kUp = 3, kExp = 4 };

// weight (height * width) = w(Up) of the depth (height * width), row-major. Up is 0 everywhere
// when the magnitude is flat or holds a NaN (as torch's aminmax, which propagates NaN).
void uncertainty_weight(const float* depth, int64_t height, int64_t width, Weighting weighting,
                        float* weight);

// The mean of weight * |render - target| over the `pixels` pixels, or over the flat indices
// sample[0 .. sample_count) when `sample` is not null (distinct indices); `weight` may be null
// (1). Writes grad (pixels,) = d mean / d render: weight * sign(render - target) / count at the
// pixels counted, 0 elsewhere. The sum is taken in fixed blocks in double, whatever the threads:
// the same inputs give the same loss.
double weighted_l1(const float* render, const float* target, const float* weight, int64_t pixels,
                   const int64_t* sample, int64_t sample_count, float* grad);

}  // namespace edgedog
