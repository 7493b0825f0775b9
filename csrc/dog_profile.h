// The peak-normalised Difference-of-Gaussians profile and its derivatives (docs/METHOD.md):
//   D(u; t) = [exp(-u) - t exp(-t u)] / (1 - t),  u = q / (2a),  t in [0, 1).
// For s = 1 - t >= 0.5 the direct form is exact; below, the form
//   D = exp(-t u) - u exp(-u) phi(s u),  phi(x) = (exp(x) - 1) / x,
// avoids the 0/0 of t -> 1. Same branches as renderer/_torch_ref.py.
#pragma once

#include <cmath>

#include "portable.h"

namespace edgedog {

constexpr float kSeriesLimit = 0.1f;  // |x| below: Taylor series for phi and phi'
constexpr float kNearLogT = 0.5f;     // s below: the cancellation-free form

// phi(x) = (e^x - 1) / x and its derivative psi(x) = (x e^x - e^x + 1) / x^2.
EDGEDOG_HD inline void phi_psi(float x, float& phi, float& psi) {
  if (std::fabs(x) < kSeriesLimit) {
    phi = 1.f + x * (1.f / 2 + x * (1.f / 6 + x * (1.f / 24 + x * (1.f / 120))));
    psi = 1.f / 2 + x * (1.f / 3 + x * (1.f / 8 + x * (1.f / 30 + x * (1.f / 144))));
  } else {
    const float em1 = std::expm1(x);
    phi = em1 / x;
    psi = (x * (em1 + 1.f) - em1) / (x * x);
  }
}

// The exponentials (and, near t = 1, the series) that D and its derivatives share: the forward
// and backward passes compute them once per (primitive, pixel).
struct DogTerms {
  float e_u, e_tu;  // exp(-u), exp(-t u)
  float phi, psi;   // phi(s u), psi(s u); set only when s < kNearLogT
};

// D(u; t), keeping in `k` what `dog_derivatives` needs.
EDGEDOG_HD inline float dog_value(float u, float t, DogTerms& k) {
  const float s = 1.f - t;
  k.e_u = std::exp(-u);
  k.e_tu = std::exp(-t * u);
  if (s >= kNearLogT) return (k.e_u - t * k.e_tu) / s;
  phi_psi(s * u, k.phi, k.psi);
  return k.e_tu - u * k.e_u * k.phi;
}

// dD/du and dD/dt at the (u, t) that `dog_value` filled `k` for.
EDGEDOG_HD inline void dog_derivatives(float u, float t, const DogTerms& k, float& d_du, float& d_dt) {
  const float s = 1.f - t;
  if (s >= kNearLogT) {
    const float numerator = k.e_u - t * k.e_tu;
    d_du = (-k.e_u + t * t * k.e_tu) / s;
    d_dt = (k.e_tu * (t * u - 1.f) * s + numerator) / (s * s);
    return;
  }
  d_du = u * k.e_u * k.phi + (s - 2.f) * k.e_tu;
  d_dt = -u * k.e_tu + u * u * k.e_u * k.psi;
}

}  // namespace edgedog
