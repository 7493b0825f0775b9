"""The 3D view with a scene's structure-from-motion points: a COLMAP scene's sparse points (what
`edgedog sfm` recovered with its cameras), drawn in their own colours while `Display.sfm_points`."""

from __future__ import annotations

import numpy as np
from edgedog.app.view3d import View3D

LAYER = "sfm points"
POINT_SIZE = 2.0
"""Pixels across one point."""


class PointsView(View3D):
    """View3D and a layer of points that stays until the next scene.

    Attributes:
        points_shown: how many points the view draws (0 when hidden or none).
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._points: np.ndarray | None = None
        self._colors: np.ndarray | None = None
        self.points_shown = 0

    def set_points(self, points: np.ndarray | None, colors: np.ndarray | None) -> None:
        """The scene's (N, 3) points and (N, 3) uint8 colours (None: white), or None for none;
        after `set_scene`."""
        self._points = None if points is None or not len(points) else np.asarray(points, np.float32)
        self._colors = None if colors is None else np.asarray(colors, np.float32) / 255.0
        self.lines.remove(LAYER)
        self.points_shown = 0
        self._dirty = True

    def sync_points(self, shown: bool) -> None:
        """Show or hide the points (uploads only on a change)."""
        count = 0 if not shown or self._points is None else len(self._points)
        if count == self.points_shown:
            return
        if count:
            colors = (1.0, 1.0, 1.0) if self._colors is None else self._colors
            self.lines.set_points(LAYER, self._points, colors, POINT_SIZE)
        else:
            self.lines.remove(LAYER)
        self.points_shown = count
        self._dirty = True  # View3D re-draws its picture only when it changed
