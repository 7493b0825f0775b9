"""Whether a frame must be drawn, and where: what imgui would draw now against what the window
shows.

A software OpenGL pays for every pixel of every frame (tens of milliseconds of CPU for a large
window), while most frames of a training run repeat the last one: the loop builds each frame
(cheap: imgui's draw lists) and draws and presents it only when its draw data differs from the
frame shown, a picture it shows was re-drawn (the 3D view, the inspectors), or imgui has a
texture to upload.

Where the back buffer keeps the last frame after a swap (a software OpenGL's does: it is a plain
image copied to the window), only the region that changed is drawn again: each panel's draw
list is compared with its own in the frame shown, and the rectangle around those that differ
(as shown before and now) is cleared and drawn, every draw command clipped to it; the whole
frame when that covers most of the window. While the user orbits the 3D view, that is mostly the
view alone.
"""

from __future__ import annotations

import ctypes
import math
import struct
import zlib
from collections.abc import Mapping

import numpy as np
from imgui_bundle import imgui

VERTEX_BYTES = 20
"""sizeof(ImDrawVert): position (2 floats), texture coordinates (2 floats), colour (4 bytes)."""
WHOLE_SHARE = 0.6
"""A region that changed larger than this share of the window: the whole frame is drawn (as
cheap, and no clipping to do)."""
Rect = tuple[float, float, float, float]
"""(x0, y0, x1, y1) in imgui's display coordinates (points)."""


def vertex_bytes(draw_list) -> bytes:
    """A copy of a draw list's vertices (VERTEX_BYTES each)."""
    vertices = draw_list.vtx_buffer
    if not vertices.size():
        return b""
    return ctypes.string_at(vertices.data_address(), vertices.size() * VERTEX_BYTES)


def list_digest(draw_list, vertices: bytes | None = None) -> int:
    """A checksum of what one draw list draws: its vertices (`vertex_bytes`, given or read) and
    the number of its commands."""
    data = vertex_bytes(draw_list) if vertices is None else vertices
    return zlib.crc32(data, zlib.crc32(struct.pack("i", draw_list.cmd_buffer.size())))


def draw_digest(draw_data: imgui.ImDrawData) -> int:
    """A checksum of what `draw_data` draws: the display's size and each draw list's digest."""
    size = draw_data.display_size
    digest = zlib.crc32(struct.pack("2f", size.x, size.y))
    for draw_list in draw_data.cmd_lists:
        digest = zlib.crc32(struct.pack("I", list_digest(draw_list)), digest)
    return digest


def list_state(draw_list) -> tuple[int, Rect | None]:
    """A draw list's digest (as `list_digest`) and the rectangle it can touch: its vertices'
    bounds within its clip rectangles (None when it draws nothing)."""
    data, commands = vertex_bytes(draw_list), draw_list.cmd_buffer
    digest = list_digest(draw_list, data)
    if not data:
        return digest, None
    positions = np.frombuffer(data, np.float32).reshape(-1, VERTEX_BYTES // 4)[:, :2]
    low, high = positions.min(axis=0), positions.max(axis=0)
    clip = None
    for index in range(commands.size()):
        rect = commands[index].clip_rect
        clip = union(clip, (rect.x, rect.y, rect.z, rect.w))
    x0, y0, x1, y1 = clip
    return digest, (max(float(low[0]), x0), max(float(low[1]), y0), min(float(high[0]), x1),
                    min(float(high[1]), y1))


def union(a: Rect | None, b: Rect | None) -> Rect | None:
    if a is None or b is None:
        return a if b is None else b
    return min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])


def owner(draw_list) -> str:
    """The name of the window a draw list belongs to ('' when imgui_bundle does not say)."""
    return getattr(draw_list, "_owner_name", "") or ""


def textures_pending(draw_data: imgui.ImDrawData) -> bool:
    """Whether imgui asks the renderer to create, update or destroy a texture (e.g. new glyphs)."""
    return any(texture.status != imgui.ImTextureStatus.ok for texture in draw_data.textures)


def clip_rects(draw_data: imgui.ImDrawData) -> list[list[Rect]]:
    """Every draw command's clip rectangle, per draw list, copied (imgui_bundle's `clip_rect` is
    a view of the command's own, which `clip_to` overwrites)."""
    return [[(clip.x, clip.y, clip.z, clip.w) for clip in (commands[index].clip_rect for index in
                                                             range(commands.size()))]
            for commands in (draw_list.cmd_buffer for draw_list in draw_data.cmd_lists)]


def clip_to(draw_data: imgui.ImDrawData, region: Rect, original: list[list[Rect]]) -> None:
    """Clip every draw command (its `original` clip rectangle) to `region` (a command left with
    nothing is skipped by the renderer), so that drawing the frame touches no pixel outside it."""
    x0, y0, x1, y1 = region
    for draw_list, clips in zip(draw_data.cmd_lists, original):
        commands = draw_list.cmd_buffer
        for index, clip in enumerate(clips):
            commands[index].clip_rect = imgui.ImVec4(max(clip[0], x0), max(clip[1], y0), min(clip[2], x1),
                                                     min(clip[3], y1))


def _pixel_corners(region: Rect, draw_data: imgui.ImDrawData) -> tuple[int, int, int, int]:
    """`region`'s corners in framebuffer pixels (y down), widened to whole pixels."""
    scale, origin = draw_data.framebuffer_scale, draw_data.display_pos
    return (math.floor((region[0] - origin.x) * scale.x), math.floor((region[1] - origin.y) * scale.y),
            math.ceil((region[2] - origin.x) * scale.x), math.ceil((region[3] - origin.y) * scale.y))


def aligned(region: Rect, draw_data: imgui.ImDrawData) -> Rect:
    """`region` widened to whole framebuffer pixels: the renderer truncates a clip rectangle's
    corner and size to pixels separately, so that a fractional one leaves a row or column that
    the clear touched undrawn."""
    scale, origin = draw_data.framebuffer_scale, draw_data.display_pos
    x0, y0, x1, y1 = _pixel_corners(region, draw_data)
    return (origin.x + x0 / scale.x, origin.y + y0 / scale.y,
            origin.x + x1 / scale.x, origin.y + y1 / scale.y)


def pixel_box(region: Rect, draw_data: imgui.ImDrawData, height: int) -> tuple[int, int, int, int]:
    """`region` as GL's (x, y, width, height) in framebuffer pixels (y from the bottom), widened
    to whole pixels."""
    x0, y0, x1, y1 = _pixel_corners(region, draw_data)
    return x0, height - y1, max(x1 - x0, 0), max(y1 - y0, 0)


class Redraw:
    """Remembers the frame shown; `needed` says whether the next one differs from it and sets
    `region`: the rectangle to draw again, None for the whole window.

    Args:
        partial: whether the back buffer keeps the frame shown after a swap, so that drawing a
            region of it is enough (else a frame that differs is drawn whole).
    """

    def __init__(self, partial: bool = False):
        self.partial = partial
        self.region: Rect | None = None
        self._shown: tuple[int, object] | None = None
        self._lists: dict[tuple[str, int], tuple[int, Rect | None]] = {}
        self._pictures: Mapping[str, int] | None = None

    def invalidate(self) -> None:
        """Draw the next frame whole (the window was exposed, or the back buffer is unknown)."""
        self._shown, self._lists, self._pictures = None, {}, None

    def needed(self, draw_data: imgui.ImDrawData, pictures: int | Mapping[str, int]) -> bool:
        """Whether to draw this frame: its draw data or `pictures` (counts of re-drawn images it
        shows: one count, or one per window that shows them) differ from the frame shown last, or
        a texture waits; noted as shown if so."""
        pending = textures_pending(draw_data)
        if not self.partial:
            frame = (draw_digest(draw_data), pictures)
            self.region = None
            if frame == self._shown and not pending:
                return False
            self._shown = frame
            return True
        size = draw_data.display_size
        lists, seen = {}, {}
        for draw_list in draw_data.cmd_lists:
            name = owner(draw_list)
            seen[name] = seen.get(name, -1) + 1
            lists[(name, seen[name])] = list_state(draw_list)
        old_size, old_lists, old_pictures = self._shown, self._lists, self._pictures
        self._shown, self._lists, self._pictures = (size.x, size.y), lists, pictures
        if old_size != (size.x, size.y) or pending or not isinstance(pictures, Mapping) or not isinstance(
                old_pictures, Mapping):
            self.region = None  # the whole window: its first frame, a new size, new textures
            return True
        dirty = []
        for key in lists.keys() | old_lists.keys():
            now, before = lists.get(key), old_lists.get(key)
            if now != before:  # drawn, moved or gone: where it is and where it was
                dirty += [entry[1] for entry in (now, before) if entry is not None and entry[1] is not None]
        for window, count in pictures.items():
            if count != old_pictures.get(window):  # its picture was re-drawn: the window's lists
                dirty += [rect for (name, _), (_, rect) in lists.items()
                          if rect is not None and (name == window or name.startswith(window + "/"))]
        region = None
        for rect in dirty:
            if rect[2] > rect[0] and rect[3] > rect[1]:
                region = union(region, rect)
        if region is None:
            return False
        # One pass at most: with a software OpenGL each pass costs every vertex of the commands it
        # touches, and one that waits for the last holds the GIL. A large region: the whole frame.
        area = (region[2] - region[0]) * (region[3] - region[1])
        self.region = None if area > WHOLE_SHARE * size.x * size.y else region
        return True
