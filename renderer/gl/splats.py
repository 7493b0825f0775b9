"""The DoG splat renderer: one instanced quad per primitive, composited front to back.

Per primitive, the vertex shader (shaders/splats.vert) projects the mean and the 2D covariance
and sizes the quad from the footprint's support; the fragment shader (shaders/splats.frag)
evaluates D(u; t) and alpha = min(0.99, o D). Instances are drawn in camera-depth order with
premultiplied "under" blending, which sums c_i alpha_i T_i like the training rasterizer. The
parameters live in a float texture array, uploaded once per model version; a frame uploads
only the depth order.
"""

from __future__ import annotations

from typing import Protocol

import moderngl
import numpy as np
import torch
from edgedog.renderer.config import ALPHA_MAX, ALPHA_MIN, FRUSTUM_SLACK, RasterConfig
from edgedog.renderer.footprint import NEAR_LOG_T, SERIES_LIMIT, support_u
from edgedog.renderer.gl.programs import load_program
from edgedog.renderer.primitives import RasterCamera, dog_shape

from edgedog.primitives import SCHEMA
from edgedog.scenes.camera import Camera

TEXTURE_WIDTH = 1024
"""Primitives per row of the parameter texture (OpenGL 3.3 guarantees textures this wide)."""
# Texture layers, one texel per primitive in each (shaders/splats.vert fetches them by number):
# 0 (mean xyz, opacity), 1 (scale xyz, a), 2 quaternion wxyz, 3 (t, u_s, 0, 0), 4 (colour rgb, 1).
LAYERS = 5
COLOR_LAYER = 4


class SplatSource(Protocol):
    """What the renderer draws; the trainer's Snapshot is one.

    Attributes: means (N, 3), scales (N, 3) activated, quats (N, 4) wxyz any norm, opacity (N,)
    activated, k_raw (N, 2) raw DoG shape.
    """

    means: np.ndarray
    scales: np.ndarray
    quats: np.ndarray
    opacity: np.ndarray
    k_raw: np.ndarray


def splat_texels(splats: SplatSource, config: RasterConfig) -> tuple[np.ndarray, np.ndarray]:
    """Per-primitive texels of layers 0-3 and which primitives can be drawn at all.

    a, t come from `dog_shape` and the support u_s from `support_u`, the training definitions.
    Returns:
        texels: (N, 4, 4) float32; drawable: (N,) bool, all inputs finite and u_s > 0.
    """
    n = len(splats.means)
    fields = {p.activated: p.shape(n) for p in SCHEMA}
    arrays = {name: np.asarray(getattr(splats, name), np.float32) for name in fields}
    for name, shape in fields.items():
        if arrays[name].shape != shape:
            raise ValueError(f"{name} has shape {arrays[name].shape}, expected {shape}")
    a, t = dog_shape(torch.tensor(arrays["k_raw"]), config)  # copies: snapshots may be read-only
    support = support_u(torch.tensor(arrays["opacity"]), t).numpy()
    texels = np.zeros((n, 4, 4), np.float32)
    texels[:, 0] = np.column_stack([arrays["means"], arrays["opacity"]])
    texels[:, 1] = np.column_stack([arrays["scales"], a.numpy()])
    texels[:, 2] = arrays["quats"]
    texels[:, 3, :2] = np.column_stack([t.numpy(), support])
    drawable = np.isfinite(texels).all(axis=(1, 2)) & (support > 0)
    return texels, drawable


def depth_order(means: np.ndarray, drawable: np.ndarray, w2c: np.ndarray, near: float) -> np.ndarray:
    """(M,) uint32 indices of the drawable primitives in front of `near`, nearest first.

    Args: means (N, 3); drawable (N,) bool; w2c (4, 4) OpenCV world-to-camera.
    Ties keep index order, as the training rasterizer's stable sort does.
    """
    z = means.astype(np.float64) @ w2c[2, :3] + w2c[2, 3]
    candidates = np.flatnonzero(drawable & (z > near))
    return candidates[np.argsort(z[candidates], kind="stable")].astype(np.uint32)


def _texture_rows(n: int) -> int:
    return max(1, -(-n // TEXTURE_WIDTH))


def _as_layer(values: np.ndarray, n: int) -> np.ndarray:
    """(N, 4) texels -> (rows, TEXTURE_WIDTH, 4), zero-padded, as one texture layer."""
    layer = np.zeros((_texture_rows(n) * TEXTURE_WIDTH, 4), np.float32)
    layer[:n] = values
    return layer.reshape(-1, TEXTURE_WIDTH, 4)


class SplatRenderer:
    """Draws primitives as DoG splats into the bound framebuffer (an OffscreenTarget or a window).

    The framebuffer must be cleared to transparent black (front-to-back compositing reads its
    alpha as 1 - T) and its viewport must be the camera's width x height.

    Attributes:
        count: how many primitives the last upload held; version: its version (None before).
    """

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.program = load_program(ctx, "splats", {"FRUSTUM_SLACK": FRUSTUM_SLACK, "ALPHA_MIN": ALPHA_MIN,
                                                     "ALPHA_MAX": ALPHA_MAX, "NEAR_LOG_T": NEAR_LOG_T,
                                                     "SERIES_LIMIT": SERIES_LIMIT})
        self.program["u_params"].value = 0
        self.count = 0
        self.version: int | None = None
        self._config: RasterConfig | None = None
        self._means = np.zeros((0, 3), np.float32)
        self._drawable = np.zeros(0, bool)
        self._params: moderngl.TextureArray | None = None
        self._order: moderngl.Buffer | None = None
        self._vao: moderngl.VertexArray | None = None

    def upload(self, splats: SplatSource, version: int, config: RasterConfig = RasterConfig()) -> bool:
        """Upload the primitives unless this (version, config) is already on the GPU.

        config gives the kernel, the k activation and eps2d. Colours reset to 1 (white).
        Returns whether anything was uploaded.
        """
        if version == self.version and config == self._config:
            return False
        texels, self._drawable = splat_texels(splats, config)
        self._means = texels[:, 0, :3]
        n = len(texels)
        layers = np.concatenate([texels, np.ones((n, 1, 4), np.float32)], axis=1)
        data = np.stack([_as_layer(layers[:, k], n) for k in range(LAYERS)])  # (LAYERS, rows, W, 4)
        if self._params is None or self._params.size[1] != data.shape[1]:
            self._release_params()
            self._params = self.ctx.texture_array((TEXTURE_WIDTH, data.shape[1], LAYERS), 4, dtype="f4")
            self._params.filter = moderngl.NEAREST, moderngl.NEAREST
        self._params.write(data.tobytes())
        if self._order is None or self._order.size < 4 * max(n, 1):
            self._release_order()
            self._order = self.ctx.buffer(reserve=4 * max(n, 1), dynamic=True)
            self._vao = self.ctx.vertex_array(self.program, [(self._order, "u/i", "in_index")])
        self.count, self.version, self._config = n, version, config
        return True

    def set_colors(self, colors: np.ndarray) -> None:
        """Per-primitive colours of the uploaded primitives: (N,) grey or (N, 3) RGB."""
        colors = np.asarray(colors, np.float32)
        rgb = np.broadcast_to(colors[:, None] if colors.ndim == 1 else colors, (self.count, 3))
        if self._params is None or self.count == 0:
            return
        layer = _as_layer(np.column_stack([rgb, np.ones(self.count, np.float32)]), self.count)
        self._params.write(layer.tobytes(), viewport=(0, 0, COLOR_LAYER, TEXTURE_WIDTH, len(layer), 1))

    def render(self, camera: Camera, near: float = RasterCamera.near) -> int:
        """Draw the uploaded primitives as seen by `camera`; returns how many were drawn.

        Args:
            camera: K (3, 3), w2c (4, 4) OpenCV world-to-camera, width, height.
            near: primitives with camera z <= near are not drawn (as the rasterizer culls them).
        """
        K, w2c = np.asarray(camera.K, np.float64), np.asarray(camera.w2c, np.float64)
        order = depth_order(self._means, self._drawable, w2c, near)
        if len(order) == 0:
            return 0
        self._order.write(order.tobytes())
        uniforms = {
            "u_rotation": w2c[:3, :3].T,  # column-major for GLSL
            "u_translation": w2c[:3, 3],
            "u_focal": (K[0, 0], K[1, 1]),
            "u_principal": (K[0, 2], K[1, 2]),
            "u_size": (camera.width, camera.height),
            "u_eps2d": self._config.eps2d,
        }
        for name, value in uniforms.items():
            self.program[name].write(np.ascontiguousarray(value, np.float32).tobytes())
        self._params.use(location=0)
        self.ctx.enable_only(moderngl.BLEND)
        self.ctx.blend_equation = moderngl.FUNC_ADD
        self.ctx.blend_func = moderngl.ONE_MINUS_DST_ALPHA, moderngl.ONE
        self._vao.render(moderngl.TRIANGLE_STRIP, vertices=4, instances=len(order))
        return len(order)

    def _release_params(self) -> None:
        if self._params is not None:
            self._params.release()
            self._params = None

    def _release_order(self) -> None:
        for obj in (self._vao, self._order):
            if obj is not None:
                obj.release()
        self._vao = self._order = None

    def release(self) -> None:
        """Free every GL object of this renderer (before the context is released)."""
        self._release_params()
        self._release_order()
        self.program.release()
