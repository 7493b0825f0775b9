"""The inspectors panel: the selected training view's image, edge map, render, depth, U and
w(U) side by side, each scalar map with its colour bar and range."""

from __future__ import annotations

from edgedog.app import layout, widgets
from edgedog.app.inspection import NAMES as INSPECTOR_NAMES
from imgui_bundle import imgui

BAR_WIDTH = 8
"""Colour bar width in unscaled points."""


def _cell(inspector, texture, colorbars, width: float, height: float) -> None:
    """One inspector fitted into width x height points: name, image, colour bar, range."""
    imgui.begin_group()
    imgui.text(inspector.name)
    bar = BAR_WIDTH * imgui.get_style().font_scale_dpi if inspector.cmap else 0.0
    spacing = imgui.get_style().item_spacing.x
    image_width, image_height = texture.size
    fit = min((width - bar - 2 * spacing) / image_width, height / image_height)
    size = imgui.ImVec2(max(image_width * fit, 1), max(image_height * fit, 1))
    imgui.image(texture.ref, size)
    if inspector.cmap:
        imgui.same_line(0, 2)
        imgui.image(colorbars[inspector.cmap].ref, imgui.ImVec2(bar, size.y))
        imgui.text_disabled(f"{inspector.lo:.3g} .. {inspector.hi:.3g}")
    if inspector.note:
        imgui.text_disabled(inspector.note)
    imgui.end_group()


def draw(studio, area: layout.Area) -> None:
    if layout.begin("Inspectors", area, imgui.WindowFlags_.no_scrollbar):
        state, views = studio.state, len(studio.session.scene)
        imgui.set_next_item_width(12 * imgui.get_font_size())
        # Numbered from 1, as the keys 1 - 9 and the help count them.
        state.view = widgets.slider_int("training view", min(state.view, views - 1) + 1, 1, views,
                                        "the view the inspectors show (keys 1 - 9 pick the first nine)") - 1
        imgui.same_line()
        if widgets.button("Snap 3D view", "look through this view's camera in the 3D view"):
            state.request("snap")
        imgui.same_line()
        imgui.text_disabled("from the latest snapshot")
        inspectors = studio.inspectors
        if not inspectors:
            imgui.text_disabled("computing...")
        else:
            avail = imgui.get_content_region_avail()
            cell = avail.x / len(INSPECTOR_NAMES)  # every slot, whether or not a run has started
            height = avail.y - 3 * imgui.get_text_line_height_with_spacing()
            start = imgui.get_cursor_pos_x()
            for i, (inspector, texture) in enumerate(zip(inspectors, studio.textures)):
                if i:
                    imgui.same_line(start + i * cell)
                _cell(inspector, texture, studio.colorbars, cell, height)
    imgui.end()
