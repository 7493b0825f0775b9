"""Rasterizer settings: the typed config users set, and the constants the kernels share.

The constants are mirrored in csrc/constants.h; tests check that both sides agree.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Literal

from edgedog.settings import Range, Settings

TILE_SIZE = 16
"""Tiles are TILE_SIZE x TILE_SIZE pixels."""
ALPHA_MIN = 1.0 / 255.0
"""A primitive whose alpha at a pixel is below this is skipped there (as in 3DGS)."""
ALPHA_MAX = 0.99
"""Per-primitive alpha is clamped to this, so the transmittance can be recovered backwards."""
EARLY_STOP_T = 0.99e-4
"""A pixel stops compositing once its transmittance would fall below this. 3DGS's 1e-4, moved
just below (1 - ALPHA_MAX)^2 = 1e-4: two saturated layers then composite in float32 and float64
alike instead of falling on either side of a tie."""
FRUSTUM_SLACK = 1.3
"""The EWA Jacobian is evaluated at directions clamped to 1.3x the half field of view."""

Kernel = Literal["dog", "gaussian"]
"""A primitive's footprint: EdgeDoG's centre-surround 'dog', or the plain 3DGS 'gaussian'."""
KActivation = Literal["sigmoid", "exp"]
"""How the raw DoG parameters k become (a, t) (docs/METHOD.md)."""
Backend = Literal["kernels", "torch"]


@dataclass(frozen=True)
class RasterConfig(Settings):
    """How primitives are turned into pixels: a section of settings (`edgedog.settings`), each
    field checked by its type when one is made.

    Attributes:
        kernel: "dog" for EdgeDoG's centre-surround footprint, "gaussian" for the plain 3DGS
            footprint (the EdgeGaussians baseline: the DoG parameters are then ignored).
        k_activation: maps the raw DoG parameters k to (a, t): "sigmoid" (the paper's choice
            for ABC) or "exp" (other data). See docs/METHOD.md.
        eps2d: screen-space dilation added to the 2D covariance's diagonal, in pixels^2
            (3DGS's anti-aliasing low-pass, without opacity compensation).
        background: colour composited behind the primitives, one value per channel; None is 0.
        backend: "kernels" (the ops registered for the primitives' device: the C++ kernels on
            the CPU) or "torch" (the slow reference, on any device).
    """

    kernel: Kernel = "dog"
    k_activation: KActivation = "sigmoid"
    eps2d: Annotated[float, Range(0)] = 0.3
    background: tuple[float, ...] | None = None
    backend: Backend = "kernels"
