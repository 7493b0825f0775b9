"""The DoG footprint's shape, shared by every backend and the GL renderer: its radial profile,
where it crosses zero, how far it reaches above the minimum alpha, and the rotation of its axes.
The maths is documented in docs/METHOD.md.
"""

from __future__ import annotations

import math

import torch
from edgedog.renderer.config import ALPHA_MIN

# |x| below this: phi and its derivative by their Taylor series (error < 2e-8).
SERIES_LIMIT = 0.1
# t above this (s = 1 - t below 0.5): the cancellation-free form of the DoG profile.
NEAR_LOG_T = 0.5


def phi(x: torch.Tensor) -> torch.Tensor:
    """(exp(x) - 1) / x, with phi(0) = 1; elementwise."""
    small = x.abs() < SERIES_LIMIT
    xs = torch.where(small, x, torch.zeros_like(x))
    series = 1 + xs / 2 + xs**2 / 6 + xs**3 / 24 + xs**4 / 120
    xl = torch.where(small, torch.ones_like(x), x)
    return torch.where(small, series, torch.expm1(xl) / xl)


def dog_profile(u: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """The peak-normalised DoG profile D(u; t) = [exp(-u) - t exp(-t u)] / (1 - t).

    Args:
        u: q / (2 a) >= 0, where q is the Mahalanobis distance under the 2D covariance.
        t: ratio of the inner to the outer covariance scale, in [0, 1).
    D(0) = 1; t = 0 is the Gaussian exp(-u); t -> 1 tends to exp(-u) (1 - u). Near t = 1 it
    is evaluated as exp(-t u) - u exp(-u) phi((1 - t) u), which has no 0/0.
    """
    s = 1 - t
    s_far = torch.where(s >= NEAR_LOG_T, s, torch.ones_like(s))
    direct = (torch.exp(-u) - t * torch.exp(-t * u)) / s_far
    s_near = torch.where(s >= NEAR_LOG_T, torch.zeros_like(s), s)
    stable = torch.exp(-(1 - s_near) * u) - u * torch.exp(-u) * phi(s_near * u)
    return torch.where(s >= NEAR_LOG_T, direct, stable)


def dog_zero_crossing(t: torch.Tensor) -> torch.Tensor:
    """u0 = -ln(t) / (1 - t), where D changes sign (inf at t = 0, 1 at t = 1)."""
    s = 1 - t
    tiny = s < 1e-4
    s_safe = torch.where(tiny, torch.ones_like(s), s)
    t_safe = torch.where(t > 0, t, torch.ones_like(t))
    u0 = torch.where(t > 0, -torch.log(t_safe) / s_safe, torch.full_like(t, math.inf))
    return torch.where(tiny, 1 + s / 2, u0)


def support_u(opacity: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """Largest u at which alpha = opacity * D(u) can still reach ALPHA_MIN (0 if never).

    D decreases on [0, u0] and D <= exp(-u) / (1 - t), so alpha >= ALPHA_MIN needs
    u <= min(u0, ln(opacity / (ALPHA_MIN (1 - t)))).
    """
    s = (1 - t).clamp_min(1e-12)
    by_alpha = torch.log((opacity / (ALPHA_MIN * s)).clamp_min(1.0))
    visible = opacity * 1.0 >= ALPHA_MIN
    return torch.where(visible, torch.minimum(dog_zero_crossing(t), by_alpha), torch.zeros_like(t))


def quat_to_rotmat(quats: torch.Tensor) -> torch.Tensor:
    """(N, 4) quaternions (w, x, y, z), any norm -> (N, 3, 3) rotations; zero -> identity."""
    norm = torch.sqrt((quats * quats).sum(-1, keepdim=True).clamp_min(1e-24))
    w, x, y, z = (quats / norm).unbind(-1)
    return torch.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], dim=-1).reshape(-1, 3, 3)
