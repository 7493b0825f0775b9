"""The triangle soup that the renderer draws."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Mesh:
    """A triangle soup with per-corner normals (sharp edges get one normal per face).

    Attributes:
        positions: (T, 3, 3) float64 corners of each triangle, counter-clockwise seen from outside.
        normals: (T, 3, 3) float64 unit normals at those corners.
    """

    positions: np.ndarray
    normals: np.ndarray
