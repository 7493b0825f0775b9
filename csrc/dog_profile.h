// The peak-normalised Difference-of-Gaussians profile and its derivatives (docs/METHOD.md):
//   D(u; t) = [exp(-u) - t exp(-t u)] / (1 - t),  u = q / (2a),  t in [0, 1).
// For s = 1 - t >= 0.5 the direct form is exact; below, the form
//   D = exp(-t u) - u exp(-u) phi(s u),  phi(x) = (exp(x) - 1) / x,
// avoids the 0/0 of t -> 1. Same branches as renderer/_torch_ref.py.
#pragma once

#include <cmath>

namespace edgedog {

constexpr float kSeriesLimit = 0.1f;  // |x| below: Taylor series for phi and phi'
constexpr float kNearLogT = 0.5f;     // s below: the cancellation-free form

// phi(x) = (e^x - 1) / x and its derivative psi(x) = (x e^x - e^x + 1) / x^2.
inline void phi_psi(float x, float& phi, float& psi) {
  if (std::fabs(x) < kSeriesLimit) {
    phi = 1.f + x * (1.f / 2 + x * (1.f / 6 + x * (1.f / 24 + x * (1.f / 120))));
    psi = 1.f / 2 + x * (1.f / 3 + x * (1.f / 8 + x * (1.f / 30 + x * (1.f / 144))));
  } else {
    const float em1 = std::expm1(x);
    phi = em1 / x;
    psi = (x * (em1 + 1.f) - em1) / (x * x);
  }
}

inline float dog_value(float u, float t) {
  const float s = 1.f - t;
  if (s >= kNearLogT) return (std::exp(-u) - t * std::exp(-t * u)) / s;
  float phi, psi;
  phi_psi(s * u, phi, psi);
  return std::exp(-t * u) - u * std::exp(-u) * phi;
}

// D, dD/du and dD/dt together.
inline float dog_value_grad(float u, float t, float& d_du, float& d_dt) {
  const float s = 1.f - t;
  const float e_u = std::exp(-u);
  const float e_tu = std::exp(-t * u);
  if (s >= kNearLogT) {
    const float numerator = e_u - t * e_tu;
    d_du = (-e_u + t * t * e_tu) / s;
    d_dt = (e_tu * (t * u - 1.f) * s + numerator) / (s * s);
    return numerator / s;
  }
  float phi, psi;
  phi_psi(s * u, phi, psi);
  d_du = u * e_u * phi + (s - 2.f) * e_tu;
  d_dt = -u * e_tu + u * u * e_u * psi;
  return e_tu - u * e_u * phi;
}

}  // namespace edgedog
