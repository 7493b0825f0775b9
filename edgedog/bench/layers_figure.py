"""The figure of a layered model: splats and curves of L0, L0+L1, L0+L1+L2, rendered offscreen.

One column per cumulative stack; the top row shows the DoG splats coloured by layer, the bottom
row the extracted curves, all from one training camera (EGL, no display needed).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np

from edgedog.curve_files import curve_polylines, read_edges
from edgedog.files import atomic_write
from edgedog.renderer.config import RasterConfig
from edgedog.scenes import Scene
from edgedog.scenes.camera import Camera
from edgedog.scenes.images import to_u8
from edgedog.train.layered import LayeredRun
from edgedog.train.trainer import read_stack, stack_snapshot

LAYER_COLORS = np.array([[1.0, 1.0, 1.0], [1.0, 0.55, 0.1], [0.2, 0.8, 1.0], [0.6, 1.0, 0.3]], np.float32)
"""RGB of layers L0, L1, L2, L3 (further layers reuse the last)."""


def layer_colors(layers: np.ndarray) -> np.ndarray:
    """(N, 3) RGB of primitives with layer indices (N,)."""
    return LAYER_COLORS[np.minimum(layers, len(LAYER_COLORS) - 1)]


def _bgr(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) float RGB in [0, 1] -> uint8 BGR for OpenCV."""
    return np.ascontiguousarray(to_u8(rgb)[..., ::-1])


def _label(panel: np.ndarray, text: str) -> np.ndarray:
    cv2.putText(panel, text, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
    return panel


def framed(camera: Camera, points: np.ndarray, fill: float = 0.85) -> Camera:
    """The camera zoomed (focal lengths scaled, principal point moved) so that the central 98 %
    of the projections of points (N, 3) fill `fill` of the image."""
    uv, depth = camera.project(points)
    uv = uv[depth > 0]
    if len(uv) < 2:
        return camera
    lo, hi = np.percentile(uv, 1, axis=0), np.percentile(uv, 99, axis=0)
    extent = np.maximum(hi - lo, 1e-6)
    zoom = fill * min(camera.width / extent[0], camera.height / extent[1])
    K = camera.K.copy()
    K[:2, :2] *= zoom
    K[:2, 2] = np.array([camera.width, camera.height]) / 2 - zoom * ((lo + hi) / 2 - camera.K[:2, 2])
    return dataclasses.replace(camera, K=K)


def render_layers_figure(run: LayeredRun, scene: Scene, out: Path, view: int = 0, size: int = 400,
                         gain: float = 1.5) -> Path:
    """Write the figure as a PNG at `out` (atomically) and return its path.

    Args:
        view: the training camera the model is seen from (scaled to `size` pixels wide and
            zoomed onto the model).
        gain: splat intensities are multiplied by this so that faint layers stay visible.
    """
    from edgedog.renderer.gl.context import offscreen_context
    from edgedog.renderer.gl.lines import LineRenderer, polyline_segments
    from edgedog.renderer.gl.splats import SplatRenderer
    from edgedog.renderer.gl.target import OffscreenTarget

    camera = scene.camera(view)
    camera = camera.scaled(size, round(camera.height * size / camera.width))
    stack = read_stack(run.layer_dir(len(run.levels) - 1))
    camera = framed(camera, stack.model.means.detach().double().numpy())
    raster = RasterConfig(kernel=run.base.model.kernel, k_activation=run.base.model.k_activation)
    ctx = offscreen_context()
    target = OffscreenTarget(ctx, camera.width, camera.height)
    splats, lines = SplatRenderer(ctx), LineRenderer(ctx)
    columns = []
    try:
        for count in range(1, len(run.levels) + 1):
            name = "+".join(f"L{i}" for i in range(count))
            chosen = stack_snapshot(stack.below(count))
            target.use()
            target.clear()
            splats.upload(chosen, count, raster)
            splats.set_colors(layer_colors(chosen.layers))
            splats.render(camera)
            splat_rgb = np.clip(target.read()[..., :3] * gain, 0, 1)
            curves = read_edges(run.path / "curves" / name / "curves.json")
            target.clear()
            lines.set_segments("curves", polyline_segments(curve_polylines(curves)), (1.0, 1.0, 1.0, 1.0))
            lines.render(camera)
            curve_rgb = target.read()[..., :3]
            columns.append(np.vstack([_label(_bgr(splat_rgb), f"{name}: {len(chosen.means)} primitives"),
                                      _label(_bgr(curve_rgb), f"{name}: {curves.num_curves} curves")]))
    finally:
        for item in (splats, lines, target):
            item.release()
        ctx.release()
    figure = np.hstack([np.pad(c, ((0, 0), (0, 4), (0, 0)), constant_values=64) for c in columns])
    ok, data = cv2.imencode(".png", figure)
    if not ok:
        raise RuntimeError(f"PNG encoding failed for {out}")
    return atomic_write(out, lambda f: f.write(data.tobytes()))
