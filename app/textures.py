"""Images shown by imgui: RGBA8 textures in the window's context, re-created only on resize."""

from __future__ import annotations

import moderngl
import numpy as np
from imgui_bundle import imgui


def texture_ref(texture: moderngl.Texture) -> imgui.ImTextureRef:
    """What imgui's OpenGL 3 backend draws: the GL texture name."""
    return imgui.ImTextureRef(texture.glo)


class ImageTexture:
    """One image for imgui, updated in place while its size stays the same."""

    def __init__(self, ctx: moderngl.Context, filter: int = moderngl.NEAREST):
        self.ctx, self.filter = ctx, filter
        self.texture: moderngl.Texture | None = None

    def set(self, rgba: np.ndarray) -> None:
        """Upload (H, W, 4) uint8, row 0 at the top (imgui's uv (0, 0))."""
        height, width = rgba.shape[:2]
        if self.texture is None or self.texture.size != (width, height):
            self.release()
            self.texture = self.ctx.texture((width, height), 4)
            self.texture.filter = self.filter, self.filter
        self.texture.write(np.ascontiguousarray(rgba, np.uint8).tobytes())

    @property
    def size(self) -> tuple[int, int]:
        """(width, height), (0, 0) before the first upload."""
        return (0, 0) if self.texture is None else self.texture.size

    @property
    def ref(self) -> imgui.ImTextureRef:
        return texture_ref(self.texture)

    def release(self) -> None:
        if self.texture is not None:
            self.texture.release()
            self.texture = None
