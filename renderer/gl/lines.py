"""Lines and points in world space: reconstructed curves, ground-truth points, camera frusta.

Named layers, each uploaded once and drawn with depth testing and premultiplied "over"
blending (after the splats, or into an empty target).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import moderngl
import numpy as np
from edgedog.renderer.gl.camera import gl_projection
from edgedog.renderer.gl.programs import load_program
from edgedog.renderer.primitives import RasterCamera

from edgedog.scenes.camera import Camera


def polyline_segments(polylines: Sequence[np.ndarray]) -> np.ndarray:
    """(S, 2, 3) segments between consecutive points of each (M, 3) polyline (M < 2 adds none)."""
    pieces = [np.stack([p[:-1], p[1:]], axis=1) for p in map(np.asarray, polylines) if len(p) >= 2]
    return np.concatenate(pieces) if pieces else np.zeros((0, 2, 3))


def frustum_segments(cameras: Sequence[Camera], depth: float) -> np.ndarray:
    """(8 C, 2, 3) per camera: its centre to the image corners at camera z = `depth`, and the
    image rectangle there. The corners are the outer pixel edges (-0.5 and size - 0.5)."""
    segments = []
    for camera in cameras:
        u = np.array([-0.5, camera.width - 0.5, camera.width - 0.5, -0.5])
        v = np.array([-0.5, -0.5, camera.height - 0.5, camera.height - 0.5])
        rays = np.linalg.solve(camera.K, np.stack([u, v, np.ones(4)]))  # (3, 4), camera z = 1
        c2w = camera.c2w()
        corners = (c2w[:3, :3] @ (depth * rays)).T + c2w[:3, 3]
        segments += [(camera.center, corner) for corner in corners]
        segments += [(corners[k], corners[(k + 1) % 4]) for k in range(4)]
    return np.asarray(segments, float).reshape(-1, 2, 3)


def _rgba(color, n: int) -> np.ndarray:
    """(n, 4) colours from one RGB(A) colour or one per item, (n, 3) or (n, 4); alpha 1 if absent."""
    color = np.asarray(color, np.float32)
    if color.shape[-1] == 3:
        color = np.concatenate([color, np.ones(color.shape[:-1] + (1,), np.float32)], axis=-1)
    return np.broadcast_to(color, (n, 4))


@dataclass
class _Layer:
    buffer: moderngl.Buffer
    vao: moderngl.VertexArray
    mode: int
    point_size: float

    def release(self) -> None:
        self.vao.release()
        self.buffer.release()


class LineRenderer:
    """Draws named layers of line segments or points into the bound framebuffer."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.program = load_program(ctx, "lines")
        self._layers: dict[str, _Layer] = {}

    def set_segments(self, name: str, segments: np.ndarray, color) -> None:
        """Layer `name` becomes these (S, 2, 3) segments; color: RGB(A), or (S, 3|4) per segment.
        Segments with a non-finite coordinate are left out."""
        segments = np.asarray(segments, np.float32).reshape(-1, 2, 3)
        colors = np.repeat(_rgba(color, len(segments))[:, None], 2, axis=1)
        self._set(name, segments.reshape(-1, 3), colors.reshape(-1, 4), moderngl.LINES, 1.0, group=2)

    def set_points(self, name: str, points: np.ndarray, color, size: float = 3.0) -> None:
        """Layer `name` becomes these (P, 3) points, `size` pixels wide; color: RGB(A) or (P, 3|4).
        Non-finite points are left out."""
        points = np.asarray(points, np.float32).reshape(-1, 3)
        self._set(name, points, _rgba(color, len(points)), moderngl.POINTS, size, group=1)

    def _set(self, name: str, positions, colors, mode: int, point_size: float, group: int) -> None:
        """Upload (V, 3) positions and (V, 4) colours; `group` vertices (a segment, a point) are kept
        or dropped together."""
        self.remove(name)
        finite = np.isfinite(positions).all(1).reshape(-1, group).all(1).repeat(group)
        vertices = np.hstack([positions, colors]).astype(np.float32)[finite]
        if len(vertices) == 0:
            return
        buffer = self.ctx.buffer(vertices.tobytes())
        vao = self.ctx.vertex_array(self.program, [(buffer, "3f 4f", "in_position", "in_color")])
        self._layers[name] = _Layer(buffer, vao, mode, point_size)

    def remove(self, name: str) -> None:
        """Drop layer `name` if present."""
        layer = self._layers.pop(name, None)
        if layer is not None:
            layer.release()

    def render(self, camera: Camera, near: float = RasterCamera.near, far: float = 1e4) -> None:
        """Draw every layer as seen by `camera`, clipped to camera z in [near, far]."""
        view_projection = gl_projection(camera.K, camera.width, camera.height, near, far) @ camera.w2c
        self.program["u_view_projection"].write(np.ascontiguousarray(view_projection.T, np.float32).tobytes())
        self.ctx.enable_only(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.PROGRAM_POINT_SIZE)
        self.ctx.blend_equation = moderngl.FUNC_ADD
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        for layer in self._layers.values():
            self.program["u_point_size"].value = layer.point_size
            layer.vao.render(layer.mode)

    def release(self) -> None:
        """Free every GL object of this renderer (before the context is released)."""
        for name in list(self._layers):
            self.remove(name)
        self.program.release()
