"""EdgeGaussians' initialisation: points drawn uniformly in a cube around the object."""

from __future__ import annotations

import numpy as np

from edgedog.init.points import InitialPoints


def uniform_init(center: np.ndarray, *, side: float, count: int,
                 scale_range: tuple[float, float] = (0.004, 0.005), seed: int = 0) -> InitialPoints:
    """`count` points uniform in the axis-aligned cube of edge `side` centred on `center`.

    EdgeGaussians' settings for ABC (objects normalised to the unit cube): 2500 points in a
    1.1-wide cube, scales uniform in [0.004, 0.005], opacity 0.08 and random rotations (the
    last two are set by the model, not here).

    Args:
        center: (3,) cube centre, world units.
        side: cube edge length, world units.
        count: number of points.
        scale_range: (low, high) of the uniformly drawn isotropic scales.
        seed: random seed; the same seed gives the same points.
    """
    center = np.asarray(center, dtype=np.float64).reshape(3)
    low, high = (float(v) for v in scale_range)
    if not (side > 0 and count >= 0 and 0 <= low <= high):
        raise ValueError(f"need side > 0, count >= 0 and 0 <= low <= high; got side={side}, "
                         f"count={count}, scale_range={scale_range}")
    rng = np.random.default_rng(seed)
    positions = center + (rng.random((count, 3)) - 0.5) * side
    scales = rng.uniform(low, high, size=count)
    report = {
        "points": int(count),
        "center": [float(c) for c in center],
        "side": float(side),
        "scale_range": [low, high],
        "seed": int(seed),
    }
    return InitialPoints(positions, scales, "uniform", report)
