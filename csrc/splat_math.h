// What one primitive does at one pixel: its tile rectangle, its footprint clipped to a tile,
// its alpha, the gradients of one (primitive, pixel) pair and the compositing "behind" it. The
// CPU kernels (tiles.cpp, rasterize.cpp) and the CUDA kernels (*_cuda.cu) share these, so both
// skip the same pixels and differentiate the same expressions. Mirrors renderer/_torch_ref.py.
#pragma once

#include <cmath>
#include <cstdint>

#include "constants.h"
#include "dog_profile.h"
#include "portable.h"
#include "rasterize.h"
#include "tiles.h"

namespace edgedog {
namespace splat {

constexpr int kTilePixels = kTileSize * kTileSize;

// std::max / std::min's results (the first argument on ties and NaN), usable on the device.
EDGEDOG_HD inline float max_of(float a, float b) { return a < b ? b : a; }
EDGEDOG_HD inline float min_of(float a, float b) { return b < a ? b : a; }

struct TileRect {
  int x0, x1, y0, y1;  // inclusive tile ranges; empty when x0 > x1
};

// The tiles whose pixel centres lie inside [m - e, m + e] (clipped to the image), computed in
// float before any integer conversion so that huge or NaN coordinates cannot overflow; culled
// primitives (valid = 0 or a zero extent) get an empty range.
EDGEDOG_HD inline TileRect tile_rect(const float* m, const float* e, bool valid, int width, int height) {
  const TileRect empty{1, 0, 1, 0};
  if (!(valid && e[0] > 0 && e[1] > 0)) return empty;
  const float px0 = max_of(ceilf(m[0] - e[0]), 0.f);
  const float px1 = min_of(floorf(m[0] + e[0]), float(width - 1));
  const float py0 = max_of(ceilf(m[1] - e[1]), 0.f);
  const float py1 = min_of(floorf(m[1] + e[1]), float(height - 1));
  if (!(px0 <= px1 && py0 <= py1)) return empty;
  return {int(px0) / kTileSize, int(px1) / kTileSize, int(py0) / kTileSize, int(py1) / kTileSize};
}

struct Tile {
  int x0, y0, width, height;  // pixel origin and size (edge tiles are smaller)
};

EDGEDOG_HD inline Tile tile_at(const TileView& tiles, int index, const Frame& f) {
  const int x0 = (index % tiles.tiles_x) * kTileSize;
  const int y0 = (index / tiles.tiles_x) * kTileSize;
  const int w = f.width - x0, h = f.height - y0;
  return {x0, y0, w < kTileSize ? w : kTileSize, h < kTileSize ? h : kTileSize};
}

// One primitive, clipped to the pixels of one tile that its support ellipse can reach.
struct Footprint {
  float mx, my, A, B, C, inv_2a, u_cut, opacity, t;
  int x0, x1, y0, y1;  // inclusive pixel range inside the tile; empty when x0 > x1

  EDGEDOG_HD bool covers(int px, int py) const { return px >= x0 && px <= x1 && py >= y0 && py <= y1; }
};

EDGEDOG_HD inline Footprint footprint(const Splats& s, int32_t i, const Tile& tile) {
  Footprint fp;
  fp.mx = s.means2d[2 * i];
  fp.my = s.means2d[2 * i + 1];
  fp.A = s.conics[3 * i];
  fp.B = s.conics[3 * i + 1];
  fp.C = s.conics[3 * i + 2];
  fp.inv_2a = 0.5f / s.a[i];
  fp.u_cut = s.support[i];
  fp.opacity = s.opacity[i];
  fp.t = s.t[i];
  const float ex = s.extents[2 * i], ey = s.extents[2 * i + 1];
  fp.x0 = int(max_of(ceilf(fp.mx - ex), float(tile.x0)));
  fp.x1 = int(min_of(floorf(fp.mx + ex), float(tile.x0 + tile.width - 1)));
  fp.y0 = int(max_of(ceilf(fp.my - ey), float(tile.y0)));
  fp.y1 = int(min_of(floorf(fp.my + ey), float(tile.y0 + tile.height - 1)));
  return fp;
}

// A footprint at one pixel: its alpha and what the backward pass reuses.
struct PixelHit {
  float dx, dy, u, D, alpha;
  DogTerms terms;  // what the backward pass's derivatives of D reuse
  bool clamped;    // alpha hit kAlphaMax: no gradient through the footprint
};

// Alpha of a footprint at pixel (px, py), or false when the primitive is skipped there. The
// forward and backward passes call this same function, so they skip the same pixels.
EDGEDOG_HD inline bool hit_pixel(const Footprint& fp, int px, int py, PixelHit& h) {
  h.dx = float(px) - fp.mx;
  h.dy = float(py) - fp.my;
  const float q = fp.A * h.dx * h.dx + 2.f * fp.B * h.dx * h.dy + fp.C * h.dy * h.dy;
  h.u = q * fp.inv_2a;
  if (!(h.u <= fp.u_cut)) return false;
  h.D = dog_value(h.u, fp.t, h.terms);
  const float raw = fp.opacity * h.D;
  h.clamped = raw > kAlphaMax;
  h.alpha = h.clamped ? kAlphaMax : raw;
  return h.alpha >= kAlphaMin;
}

// What the pixel's outputs composited behind a primitive hold, accumulated back to front.
struct Behind {
  float depth, alpha;  // the colour is kept by the caller, `channels` floats

  // Absorb a primitive of alpha `alpha`, colour c (channels) and depth z in front of it.
  EDGEDOG_HD void absorb(float alpha_i, const float* c, float z, float* color, int channels) {
    for (int ch = 0; ch < channels; ++ch) color[ch] = alpha_i * c[ch] + (1.f - alpha_i) * color[ch];
    depth = alpha_i * z + (1.f - alpha_i) * depth;
    alpha = alpha_i + (1.f - alpha_i) * alpha;
  }
};

// dL/dalpha of a primitive at a pixel, for a primitive of colour c (channels) and depth z with
// transmittance T in front of it, given the pixel's loss gradients (g_image: channels floats).
EDGEDOG_HD inline float alpha_gradient(const float* c, float z, float T, const float* behind_color,
                                       const Behind& behind, const float* g_image, float g_alpha,
                                       float g_depth, int channels) {
  float g = 0.f;
  for (int ch = 0; ch < channels; ++ch) g += (c[ch] - behind_color[ch]) * T * g_image[ch];
  g += (z - behind.depth) * T * g_depth;
  g += (1.f - behind.alpha) * T * g_alpha;
  return g;
}

// dL/d(footprint's inputs) at one pixel from dL/dalpha there (for an unclamped hit).
struct FootprintGrad {
  float mean_x, mean_y, conic_a, conic_b, conic_c, opacity, a, t;
};

EDGEDOG_HD inline FootprintGrad footprint_gradient(const Footprint& fp, const PixelHit& h, float g_alpha) {
  float dD_du, dD_dt;
  dog_derivatives(h.u, fp.t, h.terms, dD_du, dD_dt);
  FootprintGrad g;
  g.opacity = g_alpha * h.D;
  const float g_D = g_alpha * fp.opacity;
  g.t = g_D * dD_dt;
  const float g_u = g_D * dD_du;
  g.a = g_u * (-h.u * 2.f * fp.inv_2a);  // du/da = -u / a
  const float g_q = g_u * fp.inv_2a;
  g.conic_a = g_q * h.dx * h.dx;
  g.conic_b = g_q * 2.f * h.dx * h.dy;
  g.conic_c = g_q * h.dy * h.dy;
  g.mean_x = -2.f * g_q * (fp.A * h.dx + fp.B * h.dy);
  g.mean_y = -2.f * g_q * (fp.B * h.dx + fp.C * h.dy);
  return g;
}

// Where each gradient of one primitive is summed (per thread on the CPU, per warp on CUDA),
// the colours' C slots last.
enum GradSlot {
  kMeanX,
  kMeanY,
  kAbsMeanX,
  kAbsMeanY,
  kConicA,
  kConicB,
  kConicC,
  kOpacity,
  kA,
  kT,
  kDepth,
  kColors
};

// (dI/dD)^2 summed over channels: the Fisher information one unclamped hit adds to its primitive.
EDGEDOG_HD inline float fisher_term(const float* c, const float* behind_color, float T, float opacity,
                                    int channels) {
  float sum = 0.f;
  for (int ch = 0; ch < channels; ++ch) {
    const float dI_dD = (c[ch] - behind_color[ch]) * T * opacity;
    sum += dI_dD * dI_dD;
  }
  return sum;
}

}  // namespace splat
}  // namespace edgedog
