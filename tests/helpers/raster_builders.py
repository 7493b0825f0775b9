"""Random primitives for the rasterizer tests."""

from __future__ import annotations

import torch
from edgedog.renderer.primitives import Primitives

F64 = torch.float64


def random_primitives(n=150, channels=1, seed=0, spread=0.3, dtype=F64) -> Primitives:
    """Thin anisotropic primitives around (0.5, 0.5, 0.5), random rotations, opacities, DoG shapes."""
    g = torch.Generator().manual_seed(seed)
    means = 0.5 + spread * torch.randn(n, 3, generator=g, dtype=F64)
    log_scales = torch.log(torch.tensor([0.03, 0.005, 0.005], dtype=F64)) \
        + 0.3 * torch.randn(n, 3, generator=g, dtype=F64)
    quats = torch.randn(n, 4, generator=g, dtype=F64)
    opacity_logits = torch.randn(n, generator=g, dtype=F64) + 1.0
    k_raw = 0.8 * torch.randn(n, 2, generator=g, dtype=F64)
    colors = torch.rand(n, channels, generator=g, dtype=F64)
    return Primitives(*(x.to(dtype) for x in (means, log_scales, quats, opacity_logits, k_raw, colors)))
