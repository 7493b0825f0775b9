"""The 3D view: live DoG splats, extracted curves, training cameras, ground truth and pruned
primitives, drawn by the GL renderer into an offscreen target that the window shows.

`sync` brings the GPU side up to date each frame, uploading only what changed (the splats once
per snapshot version); `render` re-draws the target only when the picture would change.
"""

from __future__ import annotations

from collections.abc import Sequence

import moderngl
import numpy as np
import torch
from edgedog.app.colors import colormap, curve_palette
from edgedog.app.layers import visible_subset
from edgedog.app.state import Display
from edgedog.app.worker import Published
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.gl.camera import ViewCamera
from edgedog.renderer.gl.lines import LineRenderer, frustum_segments, polyline_segments
from edgedog.renderer.gl.splats import SplatRenderer
from edgedog.renderer.gl.target import OffscreenTarget
from edgedog.renderer.primitives import dog_shape

from edgedog.curve_files import EdgeCurves, curve_polylines
from edgedog.scenes.camera import Camera

FRUSTUM_DEPTH = 0.06
"""Frusta are drawn this deep, as a fraction of the extent of the camera centres."""
FIELD_OF_VIEW = np.radians(50)
FRAMING_DISTANCE = 1.5
"""Without ground truth, the first view is this many times farther from the scene centre than a
training camera."""
FILL = 0.8
"""With ground truth, its bounding sphere spans this share of the view's height."""
ORBIT_PER_PIXEL = 0.006
"""Radians of orbit per pixel dragged."""
ZOOM_PER_NOTCH = 0.9
CAMERA_COLOR, SELECTED_COLOR = (0.45, 0.5, 0.6), (1.0, 0.8, 0.2)
GT_COLOR, PRUNED_COLOR = (0.2, 0.85, 0.35), (1.0, 0.15, 0.1)


def looked_at(cameras: Sequence[Camera], fallback: np.ndarray) -> np.ndarray:
    """(3,) the point closest to every camera's optical axis (least squares), or `fallback` when
    the axes are (nearly) parallel."""
    system, rhs = np.zeros((3, 3)), np.zeros(3)
    for camera in cameras:
        across = np.eye(3) - np.outer(camera.forward, camera.forward)  # projects out the axis
        system += across
        rhs += across @ camera.center
    if np.linalg.cond(system) > 1e6:
        return fallback
    return np.linalg.solve(system, rhs)


def splat_values(splats, mode: str, raster: RasterConfig) -> np.ndarray | None:
    """(N,) what the splats are coloured by (see state.COLOR_MODES), None for plain white."""
    if mode == "opacity":
        return np.asarray(splats.opacity, np.float64)
    if mode in ("DoG a", "DoG t"):
        a, t = dog_shape(torch.tensor(np.asarray(splats.k_raw, np.float32)), raster)
        return (a if mode == "DoG a" else t).numpy().astype(np.float64)
    return None


class View3D:
    """The view camera, the renderers and the target they draw into.

    Attributes:
        camera: the ViewCamera (orbit, pan, zoom, snap); drawn: splats drawn by the last render;
        color_range: (lo, hi) of the splat colouring, None when white.
    """

    def __init__(self, ctx: moderngl.Context, width: int = 640, height: int = 480):
        self.ctx = ctx
        self.splats, self.lines = SplatRenderer(ctx), LineRenderer(ctx)
        self.target = self._make_target(width, height)
        self.camera = ViewCamera.looking_at((0, -3, 0), (0, 0, 0), (0, 0, 1), width, height)
        self.cameras: list[Camera] = []
        self.centre, self.drawn, self.color_range = np.zeros(3), 0, None
        self._frusta = np.zeros((0, 8, 2, 3))  # per camera: its 8 segments
        self._ground_truth: np.ndarray | None = None
        self._show_splats, self._dirty = False, True
        self._splat_key = self._color_key = self._lines_key = None
        self._splat_subset = None
        self._curves: EdgeCurves | None = None
        self._uploads = 0

    def _make_target(self, width: int, height: int) -> OffscreenTarget:
        target = OffscreenTarget(self.ctx, width, height)
        target.texture.swizzle = "RGB1"  # shown opaque: premultiplied colour over black
        return target

    @property
    def texture(self) -> moderngl.Texture:
        return self.target.texture

    # --- what is shown
    def set_scene(self, cameras: Sequence[Camera], bounds: np.ndarray, ground_truth: np.ndarray | None
                  ) -> None:
        """Take a scene's cameras and ground truth (world points, or None), and frame it."""
        self.cameras = list(cameras)
        self.centre = looked_at(cameras, np.asarray(bounds, float).mean(axis=0))
        size = float(np.linalg.norm(np.ptp([camera.center for camera in cameras], axis=0)))
        self._frusta = frustum_segments(cameras, FRUSTUM_DEPTH * size).reshape(len(cameras), -1, 2, 3)
        self._ground_truth = ground_truth
        self._lines_key = None
        self.reset()

    def reset(self) -> None:
        """Look at the point the training cameras look at, from the side of the camera that looks
        most level, with their mean up direction upwards; the ground truth, when there is some,
        fills most of the view."""
        up = -np.mean([camera.R[1] for camera in self.cameras], axis=0)  # OpenCV: image down is +y
        up = up / np.linalg.norm(up) if np.linalg.norm(up) > 1e-9 else np.array([0.0, 0.0, 1.0])
        camera = min(self.cameras, key=lambda c: abs(c.forward @ up))
        direction = camera.center - self.centre
        distance = FRAMING_DISTANCE * np.linalg.norm(direction)
        if self._ground_truth is not None and len(self._ground_truth):
            radius = np.linalg.norm(self._ground_truth - self.centre, axis=1).max()
            distance = radius / np.sin(0.5 * FIELD_OF_VIEW) / FILL
        eye = self.centre + distance * direction / np.linalg.norm(direction)
        self.camera = ViewCamera.looking_at(eye, self.centre, up, self.camera.width, self.camera.height,
                                            FIELD_OF_VIEW)
        self._dirty = True

    def sync(self, published: Published | None, raster: RasterConfig | None, display: Display, view: int,
             curves: EdgeCurves | None) -> None:
        """Upload what changed since the last call for this snapshot, display and selection."""
        show = published is not None and raster is not None and display.splats
        if show != self._show_splats:
            self._show_splats, self._dirty = show, True
        if published is not None and raster is not None:
            self._sync_splats(published, raster, display)
        pruned = published.snapshot.pruned_positions if published is not None else None
        key = (display.edges, display.cameras, display.ground_truth, display.pruned, view,
               None if pruned is None else published.key)
        if key != self._lines_key or curves is not self._curves:
            self._lines_key, self._curves = key, curves
            self._set_lines(display, view, curves, pruned)

    def _sync_splats(self, published: Published, raster: RasterConfig, display: Display) -> None:
        shown = tuple(sorted(name for name, on in display.layers.items() if on))
        key = (published.key, raster, shown)
        if key != self._splat_key:
            self._splat_subset = visible_subset(published.snapshot, display.layers)
            self._uploads += 1
            self.splats.upload(self._splat_subset, self._uploads, raster)
            self._splat_key, self._color_key, self._dirty = key, None, True
        if (key, display.color_by) != self._color_key:
            values = splat_values(self._splat_subset, display.color_by, raster)
            if values is None:
                self.color_range = None
                self.splats.set_colors(np.ones(self.splats.count))
            else:
                fixed = display.color_by == "opacity" or not len(values)
                self.color_range = (0.0, 1.0) if fixed else (float(values.min()), float(values.max()))
                self.splats.set_colors(colormap(values, *self.color_range) / 255.0)
            self._color_key, self._dirty = (key, display.color_by), True

    def _set_lines(self, display: Display, view: int, curves: EdgeCurves | None, pruned) -> None:
        """Rebuild every line layer (a few thousand vertices at most: cheaper than tracking each)."""
        for name in ("curves", "cameras", "selected camera", "ground truth", "pruned"):
            self.lines.remove(name)
        if display.edges and curves is not None and curves.num_curves:
            chains = curve_polylines(curves)
            counts = [max(len(chain) - 1, 0) for chain in chains]
            colors = np.repeat(curve_palette(len(chains)), counts, axis=0)
            self.lines.set_segments("curves", polyline_segments(chains), colors)
        if display.cameras and len(self._frusta):
            others = np.delete(self._frusta, view, axis=0) if 0 <= view < len(self._frusta) else self._frusta
            self.lines.set_segments("cameras", others, CAMERA_COLOR)
            if 0 <= view < len(self._frusta):
                self.lines.set_segments("selected camera", self._frusta[view], SELECTED_COLOR)
        if display.ground_truth and self._ground_truth is not None:
            self.lines.set_points("ground truth", self._ground_truth, GT_COLOR, 1.5)
        if display.pruned and pruned is not None and len(pruned):
            self.lines.set_points("pruned", pruned, PRUNED_COLOR, 2.5)
        self._dirty = True

    # --- the camera
    def resize(self, width: int, height: int) -> None:
        """Follow the panel's size in framebuffer pixels."""
        width, height = max(int(width), 1), max(int(height), 1)
        if (width, height) != (self.target.width, self.target.height):
            self.target.release()
            self.target = self._make_target(width, height)
            self.camera.resize(width, height)
            self._dirty = True

    def orbit(self, dx: float, dy: float) -> None:
        """Turn around the target by a drag of (dx, dy) pixels: the scene turns with the mouse
        (dragging down lifts the camera to look down on it)."""
        self.camera.orbit(-dx * ORBIT_PER_PIXEL, -dy * ORBIT_PER_PIXEL)
        self._dirty = True

    def pan(self, dx: float, dy: float) -> None:
        self.camera.pan(dx, dy)
        self._dirty = True

    def zoom(self, notches: float) -> None:
        """Mouse-wheel notches: positive moves closer."""
        self.camera.zoom(ZOOM_PER_NOTCH ** notches)
        self._dirty = True

    def snap(self, view: int) -> None:
        """Look through training camera `view`, orbiting around the scene centre afterwards."""
        camera = self.cameras[view]
        self.camera.snap_to(camera, distance=float(np.linalg.norm(self.centre - camera.center)))
        self._dirty = True

    # --- drawing
    def render(self) -> bool:
        """Re-draw the target if anything changed since the last render; returns whether it did."""
        if not self._dirty:
            return False
        self.target.use()
        self.target.clear()
        view = self.camera.camera()
        self.drawn = self.splats.render(view) if self._show_splats else 0
        self.lines.render(view)
        self._dirty = False
        return True

    def release(self) -> None:
        self.splats.release()
        self.lines.release()
        self.target.release()
