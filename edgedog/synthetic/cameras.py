"""The ABC-NEF capture: cameras on a sphere of radius 4 around (0.5, 0.5, 0.5), looking at it."""

from __future__ import annotations

import numpy as np

from edgedog.scenes.camera import Camera, intrinsics, rigid_inverse

TARGET = np.array([0.5, 0.5, 0.5])
CAMERA_DISTANCE = 4.0
FOCAL_AT_800 = 1111.11
"""ABC-NEF's focal length in pixels for 800-pixel images; scaled with the image size."""


def orbit_cameras(views: int, size: int, phase: float = 0.0) -> list[Camera]:
    """`views` cameras on a Fibonacci sphere around TARGET, looking at it, +Z world up.

    Args:
        views: number of cameras, spread evenly from the +Z pole to the -Z pole.
        size: image width and height in pixels.
        phase: turn (radians) of the whole spiral about Z: another phase gives other views.
    """
    f = FOCAL_AT_800 * size / 800
    K = intrinsics(f, f, (size - 1) / 2, (size - 1) / 2)
    cameras = []
    for i in range(views):
        z = 1 - 2 * (i + 0.5) / views
        phi = phase + i * np.pi * (3 - np.sqrt(5))
        r = np.sqrt(1 - z * z)
        center = TARGET + CAMERA_DISTANCE * np.array([r * np.cos(phi), r * np.sin(phi), z])
        forward = (TARGET - center) / np.linalg.norm(TARGET - center)
        up = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
        right = np.cross(forward, up)
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        c2w = np.eye(4)
        c2w[:3, :3] = np.stack([right, down, forward], axis=1)
        c2w[:3, 3] = center
        cameras.append(Camera(K=K, w2c=rigid_inverse(c2w), width=size, height=size))
    return cameras
