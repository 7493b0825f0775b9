"""Lens distortion in OpenCV's two models, and the pinhole camera an undistorted image has.

The datasets' camera models map onto OpenCV's:
- "opencv" (`cv2.undistort`, `cv2.initUndistortRectifyMap`): coefficients (k1, k2, p1, p2[, k3[,
  k4, k5, k6]]), radial (rational with k4..k6), and tangential; COLMAP's SIMPLE_RADIAL, RADIAL,
  OPENCV and FULL_OPENCV, nerfstudio's OPENCV;
- "fisheye" (`cv2.fisheye`): equidistant with (k1, k2, k3, k4); COLMAP's and nerfstudio's
  OPENCV_FISHEYE.
The undistortion itself is OpenCV's: nothing here evaluates a distortion polynomial.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

MODELS = ("opencv", "fisheye")


@dataclass(frozen=True)
class Distortion:
    """A camera's lens distortion.

    Attributes:
        model: "opencv" or "fisheye" (see the module's docstring).
        coefficients: OpenCV's distortion vector for that model: 4, 5 or 8 values for "opencv",
            4 for "fisheye".
    """

    model: str
    coefficients: tuple[float, ...]

    def __post_init__(self):
        sizes = (4, 5, 8) if self.model == "opencv" else (4,) if self.model == "fisheye" else ()
        if not sizes:
            raise ValueError(f"unknown distortion model {self.model!r}; expected one of {MODELS}")
        if len(self.coefficients) not in sizes:
            raise ValueError(f"{self.model} distortion takes {' or '.join(map(str, sizes))} coefficients, "
                             f"got {len(self.coefficients)}")

    @property
    def vector(self) -> np.ndarray:
        """(n,) float64 coefficients, as OpenCV's functions take them."""
        return np.asarray(self.coefficients, dtype=np.float64)

    @property
    def is_identity(self) -> bool:
        """Whether every coefficient is zero: then the camera is a pinhole already."""
        return not np.any(self.vector)


def distortion_problem(names: tuple[str, ...], values: tuple[float, ...]) -> str | None:
    """Why camera parameters `values` (named `names`, for the message) cannot be used, or None."""
    for name, value in zip(names, values):
        if not np.isfinite(value):
            return f"{name} is {value}, not a finite number"
    return None


def undistorted_intrinsics(K: np.ndarray, distortion: Distortion, width: int, height: int) -> np.ndarray:
    """(3, 3) the pinhole intrinsics of the undistorted `width` x `height` image: OpenCV's choice
    in which every output pixel sees the scene (alpha 0, balance 0), so undistorted images have no
    empty borders, whose edges a detector would draw."""
    size = (int(width), int(height))
    if distortion.model == "fisheye":
        new = cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(K, distortion.vector, size, np.eye(3),
                                                                     balance=0.0)
    else:
        new, _ = cv2.getOptimalNewCameraMatrix(K, distortion.vector, size, 0.0, size)
    return np.asarray(new, dtype=np.float64)


def undistortion_maps(K: np.ndarray, distortion: Distortion, new_K: np.ndarray, width: int,
                      height: int) -> tuple[np.ndarray, np.ndarray]:
    """The (H, W) float32 x and y maps for `cv2.remap`: where in the distorted image (intrinsics
    `K`) each pixel of the undistorted one (intrinsics `new_K`) lies."""
    size = (int(width), int(height))
    if distortion.model == "fisheye":
        return cv2.fisheye.initUndistortRectifyMap(K, distortion.vector, np.eye(3), new_K, size, cv2.CV_32FC1)
    return cv2.initUndistortRectifyMap(K, distortion.vector, None, new_K, size, cv2.CV_32FC1)


def undistort(image: np.ndarray, maps: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """`image` (H, W) or (H, W, C), any dtype cv2.remap takes, resampled bilinearly through
    `undistortion_maps`; pixels that map outside the image take the nearest border pixel."""
    return cv2.remap(image, maps[0], maps[1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
