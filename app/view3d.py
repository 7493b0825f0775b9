"""The 3D view: live DoG splats, extracted curves, training cameras, ground truth and pruned
primitives, drawn by the GL renderer into an offscreen target that the window shows.

`sync` brings the GPU side up to date each frame, uploading only what changed (the splats once
per snapshot version); `render` re-draws the target only when the picture would change. While
the camera moves the picture is drawn at a reduced resolution (with a software OpenGL, drawing
costs CPU time the training thread needs), and at full resolution once it stops.

`pick` finds the curve and the primitive under a click (app/picking.py) and highlights them;
the primitives' Fisher scores (for the "Fisher U" colouring and a picked primitive's readout)
are computed from the snapshot in a background job.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass

import moderngl
import numpy as np
import torch
from edgedog.app.colors import colormap, curve_palette
from edgedog.app.inspection import FisherScores, fisher_scores
from edgedog.app.jobs import BackgroundJob
from edgedog.app.layers import visible_members, visible_subset
from edgedog.app.picking import (
    CurvePick,
    Pick,
    PrimitivePick,
    chain_segments,
    curve_kind,
    pick_points,
    pick_segments,
    to_camera,
    to_pixels,
)
from edgedog.app.state import FISHER, Display
from edgedog.app.worker import Published
from edgedog.renderer.config import RasterConfig
from edgedog.renderer.gl.camera import ViewCamera
from edgedog.renderer.gl.lines import LineRenderer, frustum_segments, polyline_segments
from edgedog.renderer.gl.splats import SplatRenderer
from edgedog.renderer.gl.target import OffscreenTarget
from edgedog.renderer.primitives import RasterCamera, dog_shape

from edgedog.curve_files import EdgeCurves, curve_polylines
from edgedog.scenes.camera import Camera
from edgedog.train.layers import layer_name

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
MOVING_SCALE = 0.5
"""While the camera moves, the view is drawn at this share of its width and height."""
SETTLE_SECONDS = 0.25
"""The camera counts as moving this long after the last gesture."""
CAMERA_COLOR, SELECTED_COLOR = (0.45, 0.5, 0.6), (1.0, 0.8, 0.2)
GT_COLOR, PRUNED_COLOR = (0.2, 0.85, 0.35), (1.0, 0.15, 0.1)
PICKED_COLOR, PICKED_POINT, PICKED_CURVE_POINTS = (1.0, 1.0, 1.0), 9.0, 4.0
"""The picked curve (its vertices as points PICKED_CURVE_POINTS pixels wide) and the picked
primitive's centre (a point PICKED_POINT pixels wide)."""
LINE_LAYERS = ("curves", "cameras", "selected camera", "ground truth", "pruned", "picked curve", "picked")
FISHER_EVERY, FISHER_SHARE = 2.0, 0.2
"""Seconds between the starts of two Fisher score computations while training: at least
FISHER_EVERY, and long enough for them to take at most FISHER_SHARE of the time (they share the
CPU with the training)."""
FISHER_FLOOR = 1e-12
"""Fisher scores are coloured by log10(max(U, FISHER_FLOOR)) (a primitive no view sees has 0)."""


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


def _gl_finish():
    """OpenGL's glFinish through ctypes, which lets go of the GIL while it waits (None without a
    GL library)."""
    name = ctypes.util.find_library("OpenGL") or ctypes.util.find_library("GL")
    return None if name is None else ctypes.CDLL(name).glFinish


GL_FINISH = _gl_finish()


def finish_without_gil() -> None:
    """Wait for the GL commands issued so far without holding the GIL. A software OpenGL draws
    when its commands are flushed, often inside the next call that needs the result (a copy of
    the target, imgui's render: moderngl's calls hold the GIL): waiting here lets the training
    thread run meanwhile."""
    if GL_FINISH is not None:
        GL_FINISH()


def scaled_camera(camera: Camera, scale: float) -> Camera:
    """`camera` for an image `scale` times as wide and high (pixel centres kept in place)."""
    width, height = max(round(camera.width * scale), 1), max(round(camera.height * scale), 1)
    sx, sy = width / camera.width, height / camera.height
    K = np.diag([sx, sy, 1.0]) @ camera.K
    K[0, 2], K[1, 2] = sx * (camera.K[0, 2] + 0.5) - 0.5, sy * (camera.K[1, 2] + 0.5) - 0.5
    return Camera(K=K, w2c=camera.w2c, width=width, height=height)


@dataclass
class Canvas:
    """A render target and the 8-bit copy of it that the window shows (sampling the float target
    at every frame would cost more than copying it once per render)."""

    target: OffscreenTarget
    texture: moderngl.Texture
    framebuffer: moderngl.Framebuffer

    @classmethod
    def make(cls, ctx: moderngl.Context, width: int, height: int, magnified: bool = False) -> Canvas:
        """`magnified`: shown larger than drawn (smoothly); else pixel for pixel, which sampling
        the nearest texel does for less (a software OpenGL pays for each texel read)."""
        texture = ctx.texture((width, height), 4)
        smooth = moderngl.LINEAR if magnified else moderngl.NEAREST
        texture.filter = smooth, smooth
        texture.swizzle = "RGB1"  # shown opaque: premultiplied colour over black
        return cls(OffscreenTarget(ctx, width, height), texture, ctx.framebuffer([texture]))

    def release(self) -> None:
        for obj in (self.framebuffer, self.texture):
            obj.release()
        self.target.release()


class View3D:
    """The view camera, the renderers and the target they draw into.

    Attributes:
        camera: the ViewCamera (orbit, pan, zoom, snap); drawn: splats drawn by the last render;
        color_range: (lo, hi) of the splat colouring, None when white.
    """

    def __init__(self, ctx: moderngl.Context, width: int = 640, height: int = 480):
        self.ctx = ctx
        self.splats, self.lines = SplatRenderer(ctx), LineRenderer(ctx)
        self._canvases: dict[float, Canvas] = {}
        """Scale -> the canvas at that share of the view's size (full, and while moving)."""
        self._scale, self._moved = 1.0, -np.inf
        self.camera = ViewCamera.looking_at((0, -3, 0), (0, 0, 0), (0, 0, 1), width, height)
        self.cameras: list[Camera] = []
        self.centre, self.drawn, self.color_range = np.zeros(3), 0, None
        self._frusta = np.zeros((0, 8, 2, 3))  # per camera: its 8 segments
        self._ground_truth: np.ndarray | None = None
        self._show_splats, self._dirty = False, True
        self._splat_key = self._color_key = self._lines_key = None
        self._splat_subset = None
        self._curves: EdgeCurves | None = None
        self._chains: list[np.ndarray] = []
        """The shown curves as vertex chains (what is drawn and picked)."""
        self._published: Published | None = None
        self._members = np.zeros(0, np.int64)
        """The snapshot indices of the primitives drawn."""
        self._raster: RasterConfig | None = None
        self.picked: Pick | None = None
        """What the last click picked (highlighted), None before one."""
        self.fisher: FisherScores | None = None
        """The latest Fisher scores computed."""
        self.fisher_error: str | None = None
        """Why the last Fisher computation failed (None: it did not)."""
        self._fisher_job, self._fisher_asked, self._fisher_seconds = BackgroundJob("fisher"), -np.inf, 0.0
        self._uploads = 0
        self._rendered = -np.inf
        self.renders = 0
        """How many times the target was drawn (it is only when the picture changes)."""

    def _canvas(self, scale: float) -> Canvas:
        if scale not in self._canvases:
            size = scaled_camera(self.camera.camera(), scale)
            self._canvases[scale] = Canvas.make(self.ctx, size.width, size.height, magnified=scale < 1)
        return self._canvases[scale]

    @property
    def target(self) -> OffscreenTarget:
        """What the last render drew into."""
        return self._canvas(self._scale).target

    @property
    def texture(self) -> moderngl.Texture:
        """The picture to show (its row 0 is the bottom)."""
        return self._canvas(self._scale).texture

    @property
    def moving(self) -> bool:
        return time.monotonic() - self._moved < SETTLE_SECONDS

    def _moves(self) -> None:
        self._moved, self._dirty = time.monotonic(), True

    # --- what is shown
    def set_scene(self, cameras: Sequence[Camera], bounds: np.ndarray, ground_truth: np.ndarray | None
                  ) -> None:
        """Take a scene's cameras and ground truth (world points, or None), and frame it."""
        self.cameras = list(cameras)
        self.centre = looked_at(cameras, np.asarray(bounds, float).mean(axis=0))
        size = float(np.linalg.norm(np.ptp([camera.center for camera in cameras], axis=0)))
        self._frusta = frustum_segments(cameras, FRUSTUM_DEPTH * size).reshape(len(cameras), -1, 2, 3)
        self._ground_truth = ground_truth
        self._lines_key = self.picked = self.fisher = None
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
        self.home = self.camera.center.copy()
        self._dirty = True

    @property
    def at_home(self) -> bool:
        """Whether the view looks from where `reset` put it."""
        return bool(np.allclose(self.camera.center, self.home, atol=1e-6))

    def sync(self, published: Published | None, raster: RasterConfig | None, display: Display, view: int,
             curves: EdgeCurves | None) -> None:
        """Upload what changed since the last call for this snapshot, display and selection."""
        show = published is not None and raster is not None and display.splats
        if show != self._show_splats:
            self._show_splats, self._dirty = show, True
        self._published, self._raster = published, raster
        self._sync_fisher(published, raster, display)
        if published is not None and raster is not None:
            self._sync_splats(published, raster, display)
        pruned = published.snapshot.pruned_positions if published is not None else None
        if curves is not self._curves and self.picked is not None and self.picked.curve is not None:
            self.picked = dataclasses.replace(self.picked, curve=None)  # its index named another curve
        key = (display.edges, display.cameras, display.ground_truth, display.pruned, view,
               None if pruned is None else published.key, self.picked)
        if key != self._lines_key or curves is not self._curves:
            self._lines_key, self._curves = key, curves
            self._set_lines(display, view, curves, pruned)

    @staticmethod
    def _count(published: Published) -> tuple[int, int]:
        """(run, primitives) of a publication, what Fisher scores are matched by."""
        return published.run, len(published.snapshot.means)

    def _sync_fisher(self, published: Published | None, raster: RasterConfig | None, display: Display
                     ) -> None:
        """Take finished Fisher scores; compute those of the latest snapshot when the colouring or
        a picked primitive needs them, at most every FISHER_EVERY seconds."""
        done = self._fisher_job.poll()
        if done is not None and done.error is not None:
            self.fisher_error = done.error
        elif done is not None:
            self.fisher, self.fisher_error = done.value, None
            self._fisher_seconds = time.monotonic() - self._fisher_asked
            self._color_key = None
            primitive = None if self.picked is None else self.picked.primitive
            if primitive is not None and primitive.fisher is None:
                self.picked = dataclasses.replace(self.picked, primitive=primitive.scored(self.fisher))
        if published is None or raster is None:
            return
        primitive = None if self.picked is None else self.picked.primitive
        unscored = (primitive is not None and primitive.fisher is None
                    and (primitive.key[0], primitive.count) == self._count(published))
        if not (display.color_by == FISHER or unscored):
            return
        fresh = self.fisher is not None and self.fisher.key == published.key
        now = time.monotonic()
        wait = max(FISHER_EVERY, self._fisher_seconds / FISHER_SHARE)
        if fresh or self._fisher_job.busy or now - self._fisher_asked < wait:
            return
        snapshot, cameras = published.snapshot, self.cameras
        self._fisher_job.submit(published.key, lambda: FisherScores(
            published.key, snapshot.step, fisher_scores(snapshot, cameras, raster)))
        self._fisher_asked = now

    def _sync_splats(self, published: Published, raster: RasterConfig, display: Display) -> None:
        shown = tuple(sorted(name for name, on in display.layers.items() if on))
        key = (published.key, raster, shown)
        if key != self._splat_key:
            self._splat_subset = visible_subset(published.snapshot, display.layers)
            self._members = visible_members(published.snapshot, display.layers)
            self._uploads += 1
            self.splats.upload(self._splat_subset, self._uploads, raster)
            self._splat_key, self._color_key, self._dirty = key, None, True
        if (key, display.color_by) != self._color_key:
            if display.color_by == FISHER:
                scores = None if self.fisher is None else self.fisher.matching(*self._count(published))
                values = None if scores is None else np.log10(np.maximum(scores[self._members], FISHER_FLOOR))
            else:
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
        for name in LINE_LAYERS:
            self.lines.remove(name)
        self._chains = curve_polylines(curves) if display.edges and curves is not None else []
        if self._chains:
            counts = [max(len(chain) - 1, 0) for chain in self._chains]
            palette = curve_palette(len(self._chains))
            if self.picked is not None and self.picked.curve is not None:
                palette[self.picked.curve.index] = PICKED_COLOR
            colors = np.repeat(palette, counts, axis=0)
            self.lines.set_segments("curves", polyline_segments(self._chains), colors)
        if display.cameras and len(self._frusta):
            others = np.delete(self._frusta, view, axis=0) if 0 <= view < len(self._frusta) else self._frusta
            self.lines.set_segments("cameras", others, CAMERA_COLOR)
            if 0 <= view < len(self._frusta):
                self.lines.set_segments("selected camera", self._frusta[view], SELECTED_COLOR)
        if display.ground_truth and self._ground_truth is not None:
            self.lines.set_points("ground truth", self._ground_truth, GT_COLOR, 1.5)
        if display.pruned and pruned is not None and len(pruned):
            self.lines.set_points("pruned", pruned, PRUNED_COLOR, 2.5)
        if self.picked is not None and self.picked.curve is not None and self._chains:
            self.lines.set_points("picked curve", self._chains[self.picked.curve.index], PICKED_COLOR,
                                  PICKED_CURVE_POINTS)
        if self.picked is not None and self.picked.primitive is not None:
            self.lines.set_points("picked", self.picked.primitive.position, PICKED_COLOR, PICKED_POINT)
        self._dirty = True

    # --- picking
    def pick(self, x: float, y: float) -> Pick:
        """Pick the curve and the primitive nearest to view pixel (x, y) (centres at integers, row
        0 at the top) among those drawn; they are highlighted until the next pick."""
        camera, near = self.camera.camera(), RasterCamera.near
        curve = primitive = None
        segments, owners = chain_segments(self._chains)
        hit = pick_segments(camera, segments, owners, (x, y), near)
        if hit is not None:
            kind = curve_kind(hit.index, len(self._curves.lines), len(self._curves.beziers))
            curve = CurvePick(hit.index, kind, self.curve_length(hit.index))
        subset = self._splat_subset if self._show_splats else None
        hit = None if subset is None else pick_points(camera, subset.means, (x, y), near)
        if hit is not None:
            primitive = self._primitive(hit.index)
        self.picked = Pick((float(x), float(y)), curve, primitive)
        self._lines_key = None
        return self.picked

    def curve_pixel(self, index: int) -> tuple[float, float] | None:
        """The view pixel (x, y) of the middle (by length) of shown curve `index`, None when it
        lies behind the camera or off the view."""
        chain = self._chains[index]
        lengths = np.linalg.norm(np.diff(chain, axis=0), axis=1)
        ends = np.concatenate([[0.0], np.cumsum(lengths)])
        middle = np.array([np.interp(ends[-1] / 2, ends, chain[:, axis]) for axis in range(3)])
        camera = self.camera.camera()
        local = to_camera(camera, middle)
        if not local[2] > RasterCamera.near:
            return None
        x, y = to_pixels(camera, local)
        inside = -0.5 <= x < camera.width - 0.5 and -0.5 <= y < camera.height - 0.5
        return (float(x), float(y)) if inside else None

    def curve_length(self, index: int) -> float:
        """The length of shown curve `index` as drawn (a Bezier's sampled polyline), scene units."""
        return float(np.linalg.norm(np.diff(self._chains[index], axis=0), axis=1).sum())

    @property
    def curves_shown(self) -> int:
        """How many curves are drawn (and can be picked)."""
        return len(self._chains)

    def _primitive(self, shown: int) -> PrimitivePick:
        """The readout of the `shown`-th primitive drawn."""
        subset, published = self._splat_subset, self._published
        index = int(self._members[shown])
        layer = layer_name(0 if subset.layers is None else int(subset.layers[shown]))
        k = np.asarray(subset.k_raw[shown], np.float32)
        a, t = dog_shape(torch.tensor(k[None]), self._raster)
        pick = PrimitivePick(index, published.snapshot.step, published.key, len(published.snapshot.means),
                             layer, tuple(float(v) for v in subset.means[shown]),
                             tuple(float(v) for v in sorted(subset.scales[shown], reverse=True)),
                             float(subset.opacity[shown]), (float(k[0]), float(k[1])),
                             (float(a[0]), float(t[0])))
        return pick if self.fisher is None else pick.scored(self.fisher)

    # --- the camera
    def resize(self, width: int, height: int) -> None:
        """Follow the panel's size in framebuffer pixels."""
        width, height = max(int(width), 1), max(int(height), 1)
        if (width, height) != (self.camera.width, self.camera.height):
            self._release_canvases()
            self.camera.resize(width, height)
            self._dirty = True

    def orbit(self, dx: float, dy: float) -> None:
        """Turn around the target by a drag of (dx, dy) pixels: the scene turns with the mouse
        (dragging down lifts the camera to look down on it)."""
        self.camera.orbit(-dx * ORBIT_PER_PIXEL, -dy * ORBIT_PER_PIXEL)
        self._moves()

    def pan(self, dx: float, dy: float) -> None:
        self.camera.pan(dx, dy)
        self._moves()

    def zoom(self, notches: float) -> None:
        """Mouse-wheel notches: positive moves closer."""
        self.camera.zoom(ZOOM_PER_NOTCH ** notches)
        self._moves()

    def snap(self, view: int) -> None:
        """Look through training camera `view`, orbiting around the scene centre afterwards."""
        camera = self.cameras[view]
        self.camera.snap_to(camera, distance=float(np.linalg.norm(self.centre - camera.center)))
        self._dirty = True

    # --- drawing
    def render(self, every: float = 0.0) -> bool:
        """Re-draw the picture if anything changed since the last render, or at full resolution
        once the camera stopped, but not within `every` seconds of the last render (the view's
        own rate); returns whether it did."""
        scale = MOVING_SCALE if self.moving else 1.0
        now = time.monotonic()
        if (not self._dirty and scale == self._scale) or now - self._rendered < every:
            return False
        self._rendered = now
        self._scale = scale
        canvas = self._canvas(scale)
        canvas.target.use()
        canvas.target.clear()
        view = scaled_camera(self.camera.camera(), scale)
        self.drawn = self.splats.render(view) if self._show_splats else 0
        self.lines.render(view)
        finish_without_gil()  # the drawing, else done inside the copy below, which holds the GIL
        self.ctx.copy_framebuffer(canvas.framebuffer, canvas.target.framebuffer)
        finish_without_gil()
        self._dirty = False
        self.renders += 1
        return True

    def _release_canvases(self) -> None:
        for canvas in self._canvases.values():
            canvas.release()
        self._canvases = {}

    def release(self) -> None:
        self._fisher_job.wait(None)
        self.splats.release()
        self.lines.release()
        self._release_canvases()
