"""Where the panels go: a fixed tiling of the window that follows its size and DPI scale. The
side panels take their full widths on a wide window and shares of a narrow one, so the 3D view
keeps over a third of the width down to the smallest window (`edgedog.app.MIN_SIZE`).

    +----------+----------------------+---------+
    | controls |       3D view        |  plots  |
    |          +----------------------+---------+
    |          |        inspectors              |
    +----------+--------------------------------+
    | status line                               |
    +-------------------------------------------+
"""

from __future__ import annotations

from dataclasses import dataclass

from imgui_bundle import imgui

CONTROLS_WIDTH, PLOTS_WIDTH = 330, 360
"""Widths on a wide window, in unscaled points (times the DPI scale)."""
CONTROLS_MIN = 240
"""The controls' width below which their labels would be cut (unscaled points)."""
CONTROLS_SHARE, PLOTS_SHARE = 0.3, 0.22
"""Shares of a narrow window's width."""
INSPECTORS_SHARE = 0.36
"""Of the height under the 3D view and plots."""
PANEL_FLAGS = (imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
               | imgui.WindowFlags_.no_background)
"""The panels tile the window: their background is the window's, cleared at each frame (`background`),
which a software OpenGL does for far less than drawing each panel's."""


@dataclass(frozen=True)
class Area:
    """A panel's rectangle in points: top-left (x, y), width, height."""

    x: float
    y: float
    width: float
    height: float


def studio_layout() -> dict[str, Area]:
    """The panels' areas for the current display size."""
    width, height = imgui.get_io().display_size
    scale = imgui.get_style().font_scale_dpi
    status = imgui.get_frame_height_with_spacing() + 2 * imgui.get_style().window_padding.y
    controls = min(CONTROLS_WIDTH * scale, max(CONTROLS_MIN * scale, CONTROLS_SHARE * width))
    plots = min(PLOTS_WIDTH * scale, PLOTS_SHARE * width)
    body = height - status
    inspectors = round(INSPECTORS_SHARE * body)
    top = body - inspectors
    return {
        "controls": Area(0, 0, controls, body),
        "view": Area(controls, 0, width - controls - plots, top),
        "plots": Area(width - plots, 0, plots, top),
        "inspectors": Area(controls, top, width - controls, inspectors),
        "status": Area(0, body, width, status),
    }


def begin(title: str, area: Area, flags: int = 0) -> bool:
    """Begin a panel window pinned to `area` (end it with imgui.end() whatever this returns),
    outlined as imgui outlines a window with a background."""
    imgui.set_next_window_pos(imgui.ImVec2(area.x, area.y))
    imgui.set_next_window_size(imgui.ImVec2(area.width, area.height))
    shown = imgui.begin(title, None, PANEL_FLAGS | flags)[0]
    low, high = imgui.ImVec2(area.x, area.y), imgui.ImVec2(area.x + area.width, area.y + area.height)
    draw = imgui.get_window_draw_list()
    draw.push_clip_rect(low, high)
    draw.add_rect(low, high, imgui.get_color_u32(imgui.Col_.border))
    draw.pop_clip_rect()
    return shown


def background() -> tuple[float, float, float, float]:
    """The panels' background colour (the style's window background, opaque): what the window is
    cleared to."""
    color = imgui.get_style().color_(imgui.Col_.window_bg)
    return color.x, color.y, color.z, 1.0
