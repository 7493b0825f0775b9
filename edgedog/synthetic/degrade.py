"""Degradations for robustness tests: noisy images, wrong poses, missing edges, fewer views.

Each one draws from its own random stream of the scene's seed, so switching one on leaves the
others' draws (and the undegraded parts of the scene) unchanged.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np

DROPS_PER_VIEW = 3
DROP_RADIUS = 1 / 16
"""Radius of each dropped patch, as a fraction of the image width."""
STREAMS = {"views": 1, "image_noise": 2, "poses": 3, "drops": 4}


@dataclass(frozen=True)
class Degradations:
    """What to spoil in the training views (validation views stay clean).

    Attributes:
        image_noise: std of Gaussian noise added to the object's RGB values, in [0, 1] units.
        rotation_deg: every written pose is turned by exactly this angle about a random axis
            through the camera centre (the images keep the true poses).
        translation_mm: and its centre moved exactly this far in a random direction
            (1 unit = 1000 mm).
        drop_fraction: share of the views whose edge maps each lose DROPS_PER_VIEW round
            patches centred on edge pixels (missed edge segments).
        keep_views: keep only this many views, a random subset of the orbit (uneven coverage,
            unlike asking for fewer views).
    """

    image_noise: float = 0.0
    rotation_deg: float = 0.0
    translation_mm: float = 0.0
    drop_fraction: float = 0.0
    keep_views: int | None = None

    def to_json(self) -> dict:
        return dataclasses.asdict(self)


def stream(seed: int, name: str) -> np.random.Generator:
    """The random generator of one degradation."""
    return np.random.default_rng([seed, STREAMS[name]])


def kept_views(views: int, keep: int | None, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of the views to write: all of them, or a random subset of `keep`."""
    if keep is None or keep >= views:
        return np.arange(views)
    return np.sort(rng.choice(views, size=keep, replace=False))


def dropped_views(views: int, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """(views,) bool: round(fraction * views) views chosen at random."""
    chosen = np.zeros(views, bool)
    chosen[rng.choice(views, size=int(round(fraction * views)), replace=False)] = True
    return chosen


def add_image_noise(rgba: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """(H, W, 4) uint8 -> the same with N(0, sigma) noise on RGB where alpha > 0 (the
    background stays transparent)."""
    noise = rng.normal(0.0, sigma * 255.0, rgba.shape[:2] + (3,)) * (rgba[..., 3:] > 0)
    rgb = np.clip(np.round(rgba[..., :3] + noise), 0, 255).astype(np.uint8)
    return np.concatenate([rgb, rgba[..., 3:]], axis=2)


def perturb_pose(c2w: np.ndarray, degrees: float, mm: float, rng: np.random.Generator) -> np.ndarray:
    """(4, 4) camera-to-world -> the same turned by `degrees` about a random axis through the
    camera centre and moved `mm` (1 unit = 1000 mm) in a random direction."""
    axis, direction = rng.normal(size=3), rng.normal(size=3)
    rotation = cv2.Rodrigues(axis / np.linalg.norm(axis) * np.radians(degrees))[0]
    moved = c2w.copy()
    moved[:3, :3] = rotation @ c2w[:3, :3]
    moved[:3, 3] += direction / np.linalg.norm(direction) * mm / 1000.0
    return moved


def drop_segments(edges: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(H, W) float32 edge map -> a copy with DROPS_PER_VIEW patches zeroed around edge pixels."""
    ys, xs = np.nonzero(edges > 0.5)
    out = edges.copy()
    if len(xs) == 0:
        return out
    radius = max(1, int(round(DROP_RADIUS * edges.shape[1])))
    for k in rng.choice(len(xs), size=min(DROPS_PER_VIEW, len(xs)), replace=False):
        cv2.circle(out, (int(xs[k]), int(ys[k])), radius, 0.0, thickness=-1)
    return out
