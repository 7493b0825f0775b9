"""Pinhole cameras in the OpenCV convention, and conversions from the other conventions.

Conventions used everywhere in edgedog:
- world-to-camera `w2c` (4, 4): x_cam = R x_world + t; the camera looks down +Z, +Y points
  down in the image, +X right (OpenCV);
- pixel centres sit at integer coordinates: the top-left pixel covers [-0.5, 0.5]^2, so a
  centred principal point of a W-pixel-wide image is cx = (W - 1) / 2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Flips the Y and Z axes: turns an OpenGL/Blender camera frame (looks down -Z, +Y up) into an
# OpenCV one and back (the matrix is its own inverse).
OPENGL_TO_OPENCV = np.diag([1.0, -1.0, -1.0, 1.0])


@dataclass(frozen=True)
class Camera:
    """One pinhole camera without distortion.

    Attributes:
        K: (3, 3) intrinsics, float64.
        w2c: (4, 4) world-to-camera rigid transform, OpenCV convention, float64.
        width: image width in pixels.
        height: image height in pixels.
    """

    K: np.ndarray
    w2c: np.ndarray
    width: int
    height: int

    @property
    def R(self) -> np.ndarray:
        """(3, 3) world-to-camera rotation."""
        return self.w2c[:3, :3]

    @property
    def t(self) -> np.ndarray:
        """(3,) world-to-camera translation."""
        return self.w2c[:3, 3]

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in world coordinates."""
        return -self.R.T @ self.t

    @property
    def forward(self) -> np.ndarray:
        """(3,) unit viewing direction (optical axis) in world coordinates."""
        return self.R[2]

    def c2w(self) -> np.ndarray:
        """(4, 4) camera-to-world transform, OpenCV convention."""
        return rigid_inverse(self.w2c)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points.

        Args:
            points: (N, 3) world coordinates.
        Returns:
            uv: (N, 2) pixel coordinates (x right, y down; pixel centres at integers).
            depth: (N,) camera-space z; points with depth <= 0 are behind the camera and their
                uv is meaningless.
        """
        cam = points @ self.R.T + self.t
        depth = cam[:, 2]
        safe = np.where(np.abs(depth) > 1e-12, depth, 1e-12)
        uv = (cam[:, :2] / safe[:, None]) @ self.K[:2, :2].T + self.K[:2, 2]
        return uv, depth

    def pixels(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest pixel of each world point, and whether it is a pixel of this image.

        Args:
            points: (N, 3) world coordinates.
        Returns:
            pixels: (N, 2) int64 (x, y), meaningful where `inside`;
            inside: (N,) bool, in front of the camera and within the image.
        """
        uv, depth = self.project(points)
        pixels = np.rint(np.nan_to_num(uv, nan=-1.0, posinf=-1.0, neginf=-1.0)).astype(np.int64)
        inside = (depth > 0) & (pixels[:, 0] >= 0) & (pixels[:, 0] < self.width) \
            & (pixels[:, 1] >= 0) & (pixels[:, 1] < self.height)
        return pixels, inside

    def scaled(self, width: int, height: int) -> Camera:
        """The same camera for an image resized to `width` x `height` pixels.

        Scales about the image corner (-0.5, -0.5) so that pixel areas map exactly.
        """
        sx, sy = width / self.width, height / self.height
        K = self.K.copy()
        K[0, 0] *= sx
        K[0, 1] *= sx
        K[1, 1] *= sy
        K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
        K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
        return Camera(K=K, w2c=self.w2c, width=width, height=height)


def rigid_inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of a (4, 4) rigid transform [R t; 0 1]."""
    inv = np.eye(4)
    inv[:3, :3] = T[:3, :3].T
    inv[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return inv


def w2c_from_opengl_c2w(c2w_gl: np.ndarray) -> np.ndarray:
    """World-to-camera (OpenCV) from a camera-to-world matrix in OpenGL/Blender convention."""
    return rigid_inverse(c2w_gl @ OPENGL_TO_OPENCV)


def intrinsics(fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """(3, 3) intrinsics matrix."""
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def pose_problem(matrix: np.ndarray) -> str | None:
    """Why a (4, 4) or (3, 4) pose is unusable, or None when it is a proper rigid transform."""
    if matrix.shape not in ((4, 4), (3, 4)):
        return f"pose has shape {matrix.shape}, expected 4x4"
    if not np.all(np.isfinite(matrix)):
        return "pose contains NaN or Inf"
    R = matrix[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-3) or np.linalg.det(R) < 0:
        return "pose rotation is not a proper rotation (orthonormal, det +1)"
    return None


def intrinsics_problem(K: np.ndarray) -> str | None:
    """Why an intrinsics matrix is unusable, or None."""
    if K.shape != (3, 3):
        return f"intrinsics have shape {K.shape}, expected 3x3"
    if not np.all(np.isfinite(K)):
        return "intrinsics contain NaN or Inf"
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        return "focal lengths must be positive"
    return None
