#include "edge_loss.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace edgedog {
namespace {

constexpr int64_t kBlock = 4096;  // terms per partial sum of the loss
constexpr int kLanes = 8;         // independent sums within a block: vectorised, no chain of adds

inline float weight_of(float up, Weighting weighting) {
  switch (weighting) {
    case Weighting::kExpNeg:
      return std::exp(-up);
    case Weighting::kOneMinus:
      return 1.f - up;
    case Weighting::kUp:
      return up;
    case Weighting::kExp:
      return std::exp(up);
    case Weighting::kOne:
    default:
      return 1.f;
  }
}

// The row `y` of the depth clamped to the image (replicated borders).
inline const float* row_at(const float* depth, int64_t y, int64_t height, int64_t width) {
  return depth + std::clamp<int64_t>(y, 0, height - 1) * width;
}

// The squared Sobel magnitude at column x of a row, given the columns to its left and right
// (x - 1 and x + 1, or x itself at a border), as losses.depth_uncertainty computes the gradient:
// vertical smoothing then horizontal difference, horizontal smoothing then vertical difference.
// Squared: the square root, needed only off the flat pixels, waits for the second pass (GCC
// would not vectorise a loop calling sqrt, which may set errno).
inline float sobel_squared(const float* __restrict up, const float* __restrict mid,
                           const float* __restrict down, int64_t left, int64_t x, int64_t right) {
  const float gx =
      ((up[right] + down[right]) + 2.f * mid[right]) - ((up[left] + down[left]) + 2.f * mid[left]);
  const float gy = ((down[left] + down[right]) + 2.f * down[x]) - ((up[left] + up[right]) + 2.f * up[x]);
  return gx * gx + gy * gy;
}

// torch's sgn: 0 at 0 and at NaN (abs's gradient there); without branches, which random signs
// would mispredict.
inline float sign_of(float x) { return float(x > 0.f) - float(x < 0.f); }

// The sum of weight * |render - target| over pixels [begin, end), writing their gradients
// (scale * weight * sign) to grad; without a weight (kWeighted false), 1. Contiguous, unaliased
// and without a branch inside: vectorised.
template <bool kWeighted>
double block_sum(const float* __restrict render, const float* __restrict target,
                 const float* __restrict weight, int64_t begin, int64_t end, float scale,
                 float* __restrict grad) {
  double lanes[kLanes] = {};
  int64_t p = begin;
  for (; p + kLanes <= end; p += kLanes) {
    for (int j = 0; j < kLanes; ++j) {
      const float error = render[p + j] - target[p + j];
      const float w = kWeighted ? weight[p + j] : 1.f;
      grad[p + j] = scale * w * sign_of(error);
      lanes[j] += double(std::fabs(error) * w);
    }
  }
  for (; p < end; ++p) {
    const float error = render[p] - target[p];
    const float w = kWeighted ? weight[p] : 1.f;
    grad[p] = scale * w * sign_of(error);
    lanes[0] += double(std::fabs(error) * w);
  }
  double sum = 0.0;
  for (double lane : lanes) sum += lane;
  return sum;
}

// The same over the pixels sample[begin, end) (a gather: scalar).
double sampled_block_sum(const float* render, const float* target, const float* weight, const int64_t* sample,
                         int64_t begin, int64_t end, float scale, float* grad) {
  double sum = 0.0;
  for (int64_t k = begin; k < end; ++k) {
    const int64_t p = sample[k];
    const float error = render[p] - target[p];
    const float w = weight == nullptr ? 1.f : weight[p];
    grad[p] = scale * w * sign_of(error);
    sum += double(std::fabs(error) * w);
  }
  return sum;
}

}  // namespace

void uncertainty_weight(const float* depth, int64_t height, int64_t width, Weighting weighting,
                        float* weight) {
  // Pass 1: the squared Sobel magnitude into `weight`, and its range.
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  bool nan = false;
#pragma omp parallel for schedule(static) reduction(min : lo) reduction(max : hi) reduction(|| : nan)
  for (int64_t y = 0; y < height; ++y) {
    const float* __restrict up = row_at(depth, y - 1, height, width);
    const float* __restrict mid = row_at(depth, y, height, width);
    const float* __restrict down = row_at(depth, y + 1, height, width);
    float* __restrict out = weight + y * width;
    out[0] = sobel_squared(up, mid, down, 0, 0, std::min<int64_t>(1, width - 1));
    for (int64_t x = 1; x + 1 < width; ++x) out[x] = sobel_squared(up, mid, down, x - 1, x, x + 1);
    if (width > 1) out[width - 1] = sobel_squared(up, mid, down, width - 2, width - 1, width - 1);
    float row_lo[kLanes], row_hi[kLanes];
    std::fill(row_lo, row_lo + kLanes, lo);
    std::fill(row_hi, row_hi + kLanes, hi);
    int row_nan = 0;
    int64_t x = 0;
    for (; x + kLanes <= width; x += kLanes) {
      for (int j = 0; j < kLanes; ++j) {
        const float m = out[x + j];
        row_nan |= int(m != m);
        row_lo[j] = m < row_lo[j] ? m : row_lo[j];
        row_hi[j] = m > row_hi[j] ? m : row_hi[j];
      }
    }
    for (; x < width; ++x) {
      row_nan |= int(out[x] != out[x]);
      row_lo[0] = std::min(row_lo[0], out[x]);
      row_hi[0] = std::max(row_hi[0], out[x]);
    }
    nan = nan || row_nan;
    lo = std::min(lo, *std::min_element(row_lo, row_lo + kLanes));
    hi = std::max(hi, *std::max_element(row_hi, row_hi + kLanes));
  }
  // Pass 2: Up = (m - m_lo) / (m_hi - m_lo) of the magnitudes m (the square root is monotone:
  // the squares' range is the magnitudes'), then w(Up); a flat magnitude, or one holding a NaN
  // (torch's aminmax propagates it), gives Up = 0. Most pixels of an edge render lie where the
  // depth is flat (m = m_lo): w(0), computed once, serves them.
  const bool flat = nan || !(hi > lo);
  const float m_lo = std::sqrt(lo), range = std::sqrt(hi) - m_lo, at_lowest = weight_of(0.f, weighting);
  const int64_t pixels = height * width;
#pragma omp parallel for schedule(static)
  for (int64_t p = 0; p < pixels; ++p) {
    weight[p] =
        (flat || weight[p] == lo) ? at_lowest : weight_of((std::sqrt(weight[p]) - m_lo) / range, weighting);
  }
}

double weighted_l1(const float* render, const float* target, const float* weight, int64_t pixels,
                   const int64_t* sample, int64_t sample_count, float* grad) {
  const int64_t count = sample == nullptr ? pixels : sample_count;
  if (sample != nullptr) std::fill(grad, grad + pixels, 0.f);
  if (count == 0) return std::numeric_limits<double>::quiet_NaN();  // torch's mean of nothing
  const float scale = 1.f / float(count);
  const int64_t blocks = (count + kBlock - 1) / kBlock;
  std::vector<double> partial(blocks, 0.0);
#pragma omp parallel for schedule(static)
  for (int64_t b = 0; b < blocks; ++b) {
    const int64_t begin = b * kBlock, end = std::min(count, begin + kBlock);
    if (sample != nullptr) {
      partial[b] = sampled_block_sum(render, target, weight, sample, begin, end, scale, grad);
    } else if (weight != nullptr) {
      partial[b] = block_sum<true>(render, target, weight, begin, end, scale, grad);
    } else {
      partial[b] = block_sum<false>(render, target, weight, begin, end, scale, grad);
    }
  }
  double total = 0.0;
  for (double s : partial) total += s;  // in block order: the same sum whatever the threads
  return total / double(count);
}

}  // namespace edgedog
