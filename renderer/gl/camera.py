"""The studio's view camera (turntable orbit, pan, zoom, snap to a training camera), and the
OpenGL projection matching the pinhole model.

Views are `edgedog.scenes.Camera`s (OpenCV axes: x right, y down, z forward; pixel centres at
integers), so the splat renderer draws a view exactly like the training rasterizer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from edgedog.scenes.camera import Camera

MIN_POLAR = np.radians(1.0)
"""Orbits stop this close to the up axis, where the turntable's yaw would be undefined."""


def gl_projection(K: np.ndarray, width: int, height: int, near: float, far: float) -> np.ndarray:
    """(4, 4) OpenCV camera coordinates -> OpenGL clip space for a width x height viewport.

    A point lands on the same pixel as K projects it to (image row 0 at the top of the
    viewport); camera z in [near, far] maps to NDC depth [-1, 1].
    """
    P = np.zeros((4, 4))
    P[0, :3] = 2 * K[0, :3] / width
    P[0, 2] += 1 / width - 1  # pixel centre x at NDC 2 (x + 0.5) / width - 1
    P[1, 1:3] = -2 * K[1, 1:3] / height
    P[1, 2] += 1 - 1 / height  # pixel centre y at NDC 1 - 2 (y + 0.5) / height
    P[2, 2:] = (far + near) / (far - near), -2 * far * near / (far - near)
    P[3, 2] = 1.0
    return P


def _rotation_about(axis: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) rotation by `angle` radians about the unit `axis` (Rodrigues)."""
    x, y, z = axis
    cross = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


def _fitted(K: np.ndarray, size, new_size, scale: float) -> np.ndarray:
    """K with its focal lengths times `scale` and its image centre moved to the new viewport's.

    The principal point keeps its offset from the image centre, scaled; sizes are (width, height).
    """
    offset = K[:2, 2] + 0.5 - 0.5 * np.asarray(size, float)  # from the image centre, in pixels
    fitted = K * np.array([[scale], [scale], [1.0]])
    fitted[:2, 2] = 0.5 * np.asarray(new_size, float) + scale * offset - 0.5
    return fitted


@dataclass(eq=False)
class ViewCamera:
    """A camera looking at `target` from `distance` away, moved by mouse gestures.

    Attributes:
        K: (3, 3) intrinsics for the width x height viewport.
        rotation: (3, 3) world-to-camera rotation (rows: right, down, forward in world axes).
        target: (3,) the point orbited around, on the optical axis.
        distance: from the camera centre to the target.
        up: (3,) unit world axis the turntable yaws about.
        width, height: viewport size in pixels.
    """

    K: np.ndarray
    rotation: np.ndarray
    target: np.ndarray
    distance: float
    up: np.ndarray
    width: int
    height: int

    @classmethod
    def looking_at(cls, eye, target, up, width: int, height: int, fov_y: float = np.radians(50)
                   ) -> ViewCamera:
        """A camera at `eye` looking at `target`, with `up` upwards in the image; fov_y in radians."""
        eye, target = np.asarray(eye, float), np.asarray(target, float)
        up = np.asarray(up, float) / np.linalg.norm(up)
        forward = (target - eye) / np.linalg.norm(target - eye)
        right = np.cross(forward, up)  # OpenCV axes: right x down = forward, down = -up
        if not np.linalg.norm(right) > 1e-9:
            raise ValueError("the view direction must not be parallel to up")
        right /= np.linalg.norm(right)
        f = 0.5 * height / np.tan(0.5 * fov_y)
        K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1]])
        rotation = np.stack([right, np.cross(forward, right), forward])
        return cls(K, rotation, target, float(np.linalg.norm(target - eye)), up, width, height)

    @property
    def center(self) -> np.ndarray:
        """(3,) the camera centre in world coordinates."""
        return self.target - self.distance * self.rotation[2]

    def camera(self) -> Camera:
        """The current view as a pinhole camera (what the renderers draw)."""
        w2c = np.eye(4)
        w2c[:3, :3] = self.rotation
        w2c[:3, 3] = -self.rotation @ self.center
        return Camera(K=self.K.copy(), w2c=w2c, width=self.width, height=self.height)

    def snap_to(self, camera: Camera, distance: float | None = None) -> None:
        """Look exactly through a training camera, its whole image fitted into the viewport.

        The target goes `distance` (default: the current one) along its optical axis. With a
        viewport of the camera's size the view is that camera; otherwise its image is scaled
        uniformly and centred (square pixels, letterboxed).
        """
        scale = min(self.width / camera.width, self.height / camera.height)
        self.K = _fitted(camera.K, (camera.width, camera.height), (self.width, self.height), scale)
        self.rotation = camera.R.copy()
        self.distance = self.distance if distance is None else float(distance)
        self.target = camera.center + self.distance * camera.forward

    def orbit(self, yaw: float, pitch: float) -> None:
        """Turn around the target: `yaw` radians about `up` (right-handed), then `pitch` radians
        tilting the view direction towards `up`, stopping MIN_POLAR short of the up axis."""
        rotation = self.rotation @ _rotation_about(self.up, -yaw)  # rotates each axis (row) by +yaw
        polar = np.arccos(np.clip(rotation[2] @ self.up, -1, 1))  # the view direction's angle from up
        pitch = np.clip(pitch, polar - (np.pi - MIN_POLAR), polar - MIN_POLAR)
        self.rotation = rotation @ _rotation_about(rotation[0], -pitch)

    def pan(self, dx: float, dy: float) -> None:
        """Move camera and target so that the target plane follows a drag of (dx, dy) pixels."""
        right, down = self.rotation[0], self.rotation[1]
        self.target = self.target - self.distance * (dx / self.K[0, 0] * right + dy / self.K[1, 1] * down)

    def zoom(self, factor: float) -> None:
        """Move towards (factor < 1) or away from (factor > 1) the target."""
        if not factor > 0:
            raise ValueError(f"zoom factor must be positive, got {factor}")
        self.distance *= factor

    def resize(self, width: int, height: int) -> None:
        """Follow a viewport resize, keeping the vertical field of view and the image centre."""
        self.K = _fitted(self.K, (self.width, self.height), (width, height), height / self.height)
        self.width, self.height = width, height
