"""The view-dependent opacity (`model.view_opacity`): each primitive's opacity logit in a view is

    a + b . d

with a its opacity logit, b (3,) its direction coefficients (`EdgeModel.opacity_dirs`) and d the
unit direction from its centre to the view's camera centre. Our splats have no occluders: an
edge that a wall hides from most views (a concave corner) is drawn by its primitive in every
view, and the views that cannot see it penalise it as a false edge. With b, a primitive can fade
on the side from which it is hidden. The term is linear in d, so it varies smoothly over the
sphere of directions and cannot single out one view, and |b| is held to `model.view_opacity_cap`
(Adam's decoupled decay of b, `loss.view_opacity_decay`, pulls it to 0 where the views disagree).

d is treated as fixed per view (no gradient to the centres through it); a centre at the camera
centre gets d = 0, the logit a.

What reads one opacity per primitive reads its largest over the training views
(`largest_logits`): the opacity cull and its reset, primitives.ply's `opacity`, and so curve
extraction's opacity filter. Density control counts each view by the primitive's opacity there
relative to that largest (`relative_opacity`): the projection cull's share of views in which it
lands on an edge, and the Fisher score per view where it is drawn (edgedog.train.strategy).
"""

from __future__ import annotations

import dataclasses

import torch

from edgedog.renderer.primitives import Primitives, RasterCamera

MIN_DISTANCE = 1e-8
"""Scene units: closer to a camera centre than this, a primitive's direction d is 0."""


def camera_centres(cameras: list[RasterCamera], device: torch.device) -> torch.Tensor:
    """(V, 3) float32 world positions of the cameras' centres, c = -R^T t of each w2c, on `device`."""
    if not cameras:
        return torch.zeros(0, 3, device=device)
    w2c = torch.stack([camera.w2c.to("cpu", torch.float64) for camera in cameras])
    centres = -torch.einsum("vji,vj->vi", w2c[:, :3, :3], w2c[:, :3, 3])
    return centres.to(device, torch.float32)


def directions(means: torch.Tensor, centre: torch.Tensor) -> torch.Tensor:
    """(N, 3) unit directions from the centres `means` (N, 3) to `centre` (3,), without gradient;
    0 for a centre within `MIN_DISTANCE` of it."""
    with torch.no_grad():
        offsets = centre - means
        length = offsets.norm(dim=1, keepdim=True)
        return torch.where(length > MIN_DISTANCE, offsets / length.clamp_min(MIN_DISTANCE),
                           torch.zeros_like(offsets))


def view_logits(logits: torch.Tensor, dirs: torch.Tensor, means: torch.Tensor,
                centre: torch.Tensor) -> torch.Tensor:
    """(N,) opacity logits a + b . d in the view whose camera centre is `centre` (3,).

    Args: logits (N,) a; dirs (N, 3) b; means (N, 3) the primitives' centres. Differentiable in
    `logits` and `dirs`.
    """
    return logits + (dirs * directions(means, centre)).sum(dim=1)


def seen_from(primitives: Primitives, dirs: torch.Tensor, centre: torch.Tensor) -> Primitives:
    """`primitives` with the opacity logits of the view whose camera centre is `centre` (3,), for
    the rasterizer; `dirs` (N, 3) is b of each primitive."""
    return dataclasses.replace(primitives, opacity_logits=view_logits(primitives.opacity_logits, dirs,
                                                                     primitives.means, centre))


def largest_logits(logits: torch.Tensor, dirs: torch.Tensor, means: torch.Tensor,
                   centres: torch.Tensor) -> torch.Tensor:
    """(N,) each primitive's largest opacity logit over the views of `centres` (V, 3) (no
    gradient): the view-independent opacity that extraction's and the culls' thresholds read.
    With no views, the logits `a` themselves."""
    with torch.no_grad():
        best = torch.full_like(logits, -torch.inf) if len(centres) else logits.clone()
        for centre in centres:
            best = torch.maximum(best, view_logits(logits, dirs, means, centre))
        return best


def relative_opacity(logits: torch.Tensor, dirs: torch.Tensor, means: torch.Tensor,
                     centres: torch.Tensor) -> torch.Tensor:
    """(V, N) each primitive's opacity in each view of `centres` (V, 3) divided by its largest
    over them, in (0, 1] (no gradient): where it is drawn (1 everywhere when b = 0)."""
    with torch.no_grad():
        largest = torch.sigmoid(largest_logits(logits, dirs, means, centres))
        return torch.stack([torch.sigmoid(view_logits(logits, dirs, means, centre)) / largest
                            for centre in centres]) if len(centres) else torch.zeros(0, len(logits))


def cap_(dirs: torch.Tensor, cap: float) -> None:
    """Shrink in place every row of b (N, 3) longer than `cap` to length `cap`."""
    with torch.no_grad():
        # min(cap / length, 1): a row within the cap is multiplied by exactly 1.
        dirs.mul_((cap / dirs.norm(dim=1, keepdim=True).clamp_min(MIN_DISTANCE)).clamp_max(1.0))
