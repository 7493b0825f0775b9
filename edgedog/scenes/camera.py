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

from edgedog.world import MAX_COORDINATE

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

    def ray_directions(self, pixels: np.ndarray) -> np.ndarray:
        """(N, 3) world directions of the rays through pixels (N, 2), scaled so that a ray's
        parameter is its point's camera z (the camera-space direction has z = 1)."""
        homogeneous = np.c_[pixels, np.ones(len(pixels))]
        return (homogeneous @ np.linalg.inv(self.K).T) @ self.R

    def pixels(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest pixel of each world point, and whether it is a pixel of this image.

        Args:
            points: (N, 3) world coordinates.
        Returns:
            pixels: (N, 2) int64 (x, y), meaningful where `inside`;
            inside: (N,) bool, in front of the camera and within the image.
        """
        return self.nearest_pixels(*self.project(points))

    def nearest_pixels(self, uv: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`pixels` of points already projected: uv (N, 2) and depth (N,) as `project` gives them,
        for a caller that also needs the sub-pixel positions."""
        pixels = np.rint(np.nan_to_num(uv, nan=-1.0, posinf=-1.0, neginf=-1.0)).astype(np.int64)
        inside = (depth > 0) & (pixels[:, 0] >= 0) & (pixels[:, 0] < self.width) \
            & (pixels[:, 1] >= 0) & (pixels[:, 1] < self.height)
        return pixels, inside

    def reduced(self, factor: int) -> Camera:
        """The same camera for the image reduced to 1/`factor` of its size (at least a pixel a side)."""
        return self.scaled(max(1, self.width // factor), max(1, self.height // factor))

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


FIELD_OF_VIEW_DEG = (0.01, 170.0)
"""Range of a pinhole camera's field of view across the image, in degrees: wider than 170 or
narrower than 0.01 (a 10000 mm lens on a full-frame sensor gives 0.2) is a broken focal length."""


def pose_problem(matrix: np.ndarray) -> str | None:
    """Why a (4, 4) or (3, 4) pose (world-to-camera or camera-to-world) is unusable, or None when
    it is a proper rigid transform: a rotation, a last row 0 0 0 1 and a camera centre within
    MAX_COORDINATE of the origin."""
    if matrix.shape not in ((4, 4), (3, 4)):
        return f"pose has shape {matrix.shape}, expected 4x4"
    if not np.all(np.isfinite(matrix)):
        return "pose contains NaN or Inf"
    if matrix.shape == (4, 4) and not np.allclose(matrix[3], [0.0, 0.0, 0.0, 1.0], rtol=0, atol=1e-6):
        return f"pose's last row is {matrix[3].tolist()}, expected [0, 0, 0, 1]"
    R = matrix[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-3) or np.linalg.det(R) < 0:
        return "pose rotation is not a proper rotation (orthonormal, det +1)"
    # |t| is the camera centre's distance from the origin for both directions of a rigid pose.
    distance = float(np.linalg.norm(matrix[:3, 3]))
    if distance > MAX_COORDINATE:
        return (f"camera is {distance:.3g} units from the origin, more than {MAX_COORDINATE:.0e}: "
                "float32 training cannot resolve such a scene (re-centre it)")
    return None


def intrinsics_problem(K: np.ndarray, width: int, height: int) -> str | None:
    """Why the intrinsics of a `width` x `height` image are unusable, or None: they must be a
    finite upper-triangular matrix with last row 0 0 1, positive focal lengths giving a field of
    view within FIELD_OF_VIEW_DEG, a skew smaller than the focal length, and a principal point
    within one image size of the image."""
    if K.shape != (3, 3):
        return f"intrinsics have shape {K.shape}, expected 3x3"
    if not np.all(np.isfinite(K)):
        return "intrinsics contain NaN or Inf"
    if not np.allclose([K[1, 0], *K[2]], [0.0, 0.0, 0.0, 1.0], rtol=0, atol=1e-6):
        return f"intrinsics {K.tolist()} are not of the form [[fx, s, cx], [0, fy, cy], [0, 0, 1]]"
    if K[0, 0] <= 0 or K[1, 1] <= 0:
        return "focal lengths must be positive"
    low, high = FIELD_OF_VIEW_DEG
    for axis, focal, pixels in (("x", K[0, 0], width), ("y", K[1, 1], height)):
        degrees = float(np.degrees(2 * np.arctan(pixels / (2 * focal))))
        if not low <= degrees <= high:
            return (f"focal length f{axis}={focal:.6g} px gives a {degrees:.4g} degree field of view "
                    f"over {pixels} px (a pinhole camera's lies between {low} and {high})")
    if abs(K[0, 1]) > K[0, 0]:
        return f"skew {K[0, 1]:.6g} is larger than the focal length"
    cx, cy = K[0, 2], K[1, 2]
    if not (-width <= cx <= 2 * width and -height <= cy <= 2 * height):
        return f"principal point ({cx:.6g}, {cy:.6g}) lies far outside the {width}x{height} image"
    return None
