"""What every 2D edge detector provides."""

from __future__ import annotations

import abc

import numpy as np


class EdgeDetector(abc.ABC):
    """Turns a colour image into a pseudo-edge map.

    Attributes:
        name: the name users select it by, e.g. "pidinet" or "canny".
    """

    name: str

    @property
    @abc.abstractmethod
    def fingerprint(self) -> str:
        """Short string that changes whenever the maps would (weights hash, settings): the cache key."""

    @abc.abstractmethod
    def detect(self, image: np.ndarray) -> np.ndarray:
        """(H, W, 3) float32 RGB in [0, 1] -> (H, W) float32 edge map in [0, 1] (1 = edge)."""
