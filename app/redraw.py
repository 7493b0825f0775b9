"""Whether a frame must be drawn: what imgui would draw now against what the window shows.

A software OpenGL pays for every pixel of every frame (tens of milliseconds of CPU for a large
window), while most frames of a training run repeat the last one: the loop builds each frame
(cheap: imgui's draw lists) and draws and presents it only when its draw data differs from the
frame shown, a picture it shows was re-drawn (the 3D view, the inspectors), or imgui has a
texture to upload.
"""

from __future__ import annotations

import ctypes
import struct
import zlib

from imgui_bundle import imgui

VERTEX_BYTES = 20
"""sizeof(ImDrawVert): position (2 floats), texture coordinates (2 floats), colour (4 bytes)."""


def draw_digest(draw_data: imgui.ImDrawData) -> int:
    """A checksum of what `draw_data` draws: the display's size, each draw list's vertices and
    the number of its draw commands."""
    size = draw_data.display_size
    digest = zlib.crc32(struct.pack("2f", size.x, size.y))
    for draw_list in draw_data.cmd_lists:
        vertices = draw_list.vtx_buffer
        digest = zlib.crc32(struct.pack("i", draw_list.cmd_buffer.size()), digest)
        if vertices.size():
            data = ctypes.string_at(vertices.data_address(), vertices.size() * VERTEX_BYTES)
            digest = zlib.crc32(data, digest)
    return digest


def textures_pending(draw_data: imgui.ImDrawData) -> bool:
    """Whether imgui asks the renderer to create, update or destroy a texture (e.g. new glyphs)."""
    return any(texture.status != imgui.ImTextureStatus.ok for texture in draw_data.textures)


class Redraw:
    """Remembers the frame shown; `needed` says whether the next one differs from it."""

    def __init__(self):
        self._shown: tuple[int, int] | None = None

    def needed(self, draw_data: imgui.ImDrawData, pictures: int) -> bool:
        """Whether to draw this frame: its draw data or `pictures` (a count of re-drawn images
        it shows) differ from the frame shown last, or a texture waits; noted as shown if so."""
        frame = (draw_digest(draw_data), pictures)
        if frame == self._shown and not textures_pending(draw_data):
            return False
        self._shown = frame
        return True
