"""An offscreen framebuffer with float32 colour, for exact renders and read-back."""

from __future__ import annotations

import moderngl
import numpy as np


class OffscreenTarget:
    """A (height, width) RGBA float32 colour texture with a depth buffer.

    Splats write premultiplied intensity and alpha = 1 - transmittance, so `read()` holds the
    training rasterizer's image in RGB and its alpha in A. `texture` can be shown by a window.
    """

    def __init__(self, ctx: moderngl.Context, width: int, height: int):
        self.width, self.height = width, height
        self.texture = ctx.texture((width, height), 4, dtype="f4")
        self._depth = ctx.depth_renderbuffer((width, height))
        self.framebuffer = ctx.framebuffer(color_attachments=[self.texture], depth_attachment=self._depth)

    def use(self) -> None:
        """Draw into this target from now on (the viewport covers it)."""
        self.framebuffer.use()

    def clear(self) -> None:
        """Transparent black, far depth: what front-to-back splat compositing starts from."""
        self.framebuffer.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)

    def read(self) -> np.ndarray:
        """(height, width, 4) float32 RGBA, row 0 at the top of the image."""
        data = self.framebuffer.read(components=4, dtype="f4")
        return np.frombuffer(data, np.float32).reshape(self.height, self.width, 4)[::-1].copy()

    def release(self) -> None:
        """Free the framebuffer and its attachments (before the context is released)."""
        for obj in (self.framebuffer, self._depth, self.texture):
            obj.release()
