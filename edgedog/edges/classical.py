"""Weight-free edge detectors from OpenCV: they work out of the box, with no model file."""

from __future__ import annotations

import cv2
import numpy as np

from edgedog.edges.detector import EdgeDetector
from edgedog.scenes.images import to_u8


def _gray_u8(image: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(to_u8(image), cv2.COLOR_RGB2GRAY)


class SobelDetector(EdgeDetector):
    """Gradient magnitude of the lightly smoothed grey image, scaled to [0, 1].

    The magnitude is divided by `full_scale` (a step of that many grey levels between
    neighbouring pixels maps to 1) and clipped, so maps are comparable across images.
    """

    name = "sobel"

    def __init__(self, blur_sigma: float = 1.0, full_scale: float = 0.25):
        self.blur_sigma = blur_sigma
        self.full_scale = full_scale

    @property
    def fingerprint(self) -> str:
        return f"sobel-s{self.blur_sigma:g}-f{self.full_scale:g}"

    def detect(self, image: np.ndarray) -> np.ndarray:
        gray = cv2.GaussianBlur(_gray_u8(image).astype(np.float32) / 255.0, (0, 0), self.blur_sigma)
        gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3)
        gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3)
        # The 3x3 Sobel kernel weighs a unit step by 4 across its smoothing direction.
        return np.clip(np.hypot(gx, gy) / (4.0 * self.full_scale), 0.0, 1.0).astype(np.float32)


class CannyDetector(EdgeDetector):
    """Canny's thin, binary edges, softened by a Gaussian of `soften_sigma` pixels so that the
    map has the smooth profile the photometric loss needs (peak 1 on the edge).

    Args:
        low, high: the hysteresis thresholds, grey levels.
        blur_sigma: the Gaussian (pixels) the grey image is smoothed with before Canny.
        soften_sigma: the Gaussian (pixels) the binary edges are softened with.
    """

    name = "canny"

    def __init__(self, low: int = 50, high: int = 150, blur_sigma: float = 1.0, soften_sigma: float = 1.0):
        self.low, self.high, self.blur_sigma, self.soften_sigma = low, high, blur_sigma, soften_sigma

    @property
    def fingerprint(self) -> str:
        return f"canny-{self.low}-{self.high}-b{self.blur_sigma:g}-s{self.soften_sigma:g}"

    def detect(self, image: np.ndarray) -> np.ndarray:
        edges = cv2.Canny(cv2.GaussianBlur(_gray_u8(image), (0, 0), self.blur_sigma), self.low, self.high)
        soft = cv2.GaussianBlur(edges.astype(np.float32) / 255.0, (0, 0), self.soften_sigma)
        peak = 1.0 / (2 * np.pi * self.soften_sigma**2) ** 0.5  # a 1-px line's blurred peak
        return np.clip(soft / peak, 0.0, 1.0).astype(np.float32)
