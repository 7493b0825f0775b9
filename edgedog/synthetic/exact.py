"""Which curve points a camera sees, and exact edge maps: the visible feature curves drawn as
anti-aliased lines, the ideal pseudo-edge labels (detector name "exact").

A point on a sharp edge lies on the faces that meet there, so it is visible when one of the
surfaces rendered at the pixels around its projection, extended as a plane, meets the point's
viewing ray at the point itself. An occluder in front meets the ray well before it.
"""

from __future__ import annotations

import cv2
import numpy as np

from edgedog.scenes.camera import Camera
from edgedog.synthetic.features import Curve
from edgedog.synthetic.render import Render

EXACT = "exact"
PLANE_TOLERANCE = 0.003
"""How far (world units, 3 mm) along its ray a point may be from the surface seen beside it."""
GRAZING_COS = 0.02
"""Surfaces seen more obliquely than this (|cos| of the ray's angle to the normal) cannot judge."""
DRAW_STEP = 0.001
"""Spacing (world units) of the curve points drawn: well under a pixel at the orbit's distance."""
LINE_WIDTH = 2
SUBPIXEL_BITS = 4  # cv2 drawing precision: 1/16 px


def visible(points: np.ndarray, camera: Camera, render: Render) -> np.ndarray:
    """Whether each point on the mesh's surface is seen by `camera`.

    Args:
        points: (N, 3) world points lying on the rendered surface (e.g. on its feature curves).
        render: the camera's render of the mesh (depth and normals).
    Returns:
        (N,) bool.
    """
    pixels, inside = camera.pixels(points)
    rays = points - camera.center
    distance = np.linalg.norm(rays, axis=1)
    c2w, K_inv = camera.c2w(), np.linalg.inv(camera.K)
    seen = np.zeros(len(points), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            x = np.clip(pixels[:, 0] + dx, 0, camera.width - 1)
            y = np.clip(pixels[:, 1] + dy, 0, camera.height - 1)
            depth, normal = render.depth[y, x], render.normals[y, x]
            surface_cam = depth[:, None] * (np.stack([x, y, np.ones_like(x)], 1) @ K_inv.T)
            surface = surface_cam @ c2w[:3, :3].T + c2w[:3, 3]
            facing = np.einsum("ij,ij->i", normal, rays)
            usable = (depth > 0) & (np.abs(facing) > GRAZING_COS * distance)
            # Where the surface's plane meets the ray, as a multiple of the point's distance.
            t = np.einsum("ij,ij->i", normal, surface - camera.center) / np.where(usable, facing, 1.0)
            seen |= usable & (np.abs(t - 1) * distance <= PLANE_TOLERANCE)
    return seen & inside


def exact_edge_map(curves: list[Curve] | tuple[Curve, ...], camera: Camera, render: Render) -> np.ndarray:
    """(H, W) float32 in [0, 1]: the visible parts of `curves`, anti-aliased, LINE_WIDTH px wide."""
    canvas = np.zeros((camera.height, camera.width), np.uint8)
    for curve in curves:
        points = curve.at(np.linspace(0.0, 1.0, int(np.ceil(curve.length / DRAW_STEP)) + 1))
        shown = visible(points, camera, render)
        fixed = np.round(camera.project(points)[0] * (1 << SUBPIXEL_BITS)).astype(np.int32)
        bounds = np.flatnonzero(np.diff(np.r_[0, shown.astype(np.int8), 0]))  # starts and ends of runs
        runs = [fixed[a:b] for a, b in zip(bounds[::2], bounds[1::2]) if b - a >= 2]
        cv2.polylines(canvas, runs, False, 255, LINE_WIDTH, cv2.LINE_AA, SUBPIXEL_BITS)
    return canvas.astype(np.float32) / 255.0
