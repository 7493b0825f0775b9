"""The inspectors panel: the selected training view's image, edge map, render, depth, U and
w(U) side by side, each scalar map with its colour bar and range.

A click on an inspector enlarges it to the whole panel, where the wheel zooms about the mouse
and a drag pans; "all inspectors" goes back. Hovering any inspector reads out the pixel under
the mouse: the map's value (the image's RGB), the view and the pixel.
"""

from __future__ import annotations

from edgedog.app import layout, widgets
from edgedog.app.inspection import NAMES as INSPECTOR_NAMES
from edgedog.app.zoom import ImageZoom, Placement, pixel_at
from imgui_bundle import imgui

BAR_WIDTH = 8
"""Colour bar width in unscaled points."""
DRAG_BUTTONS = imgui.ButtonFlags_.mouse_button_left | imgui.ButtonFlags_.mouse_button_right
"""The buttons that pan an enlarged inspector."""


def _label(inspector) -> str:
    """The scripted driver's name of an inspector, e.g. 'inspector depth'."""
    return f"inspector {inspector.slot}"


def _hover(studio, inspector, placement: Placement) -> None:
    """Note the readout of the pixel under the mouse while the last item (an image) is hovered."""
    if not imgui.is_item_hovered():
        return
    mouse = imgui.get_io().mouse_pos
    width, height = inspector.rgba.shape[1], inspector.rgba.shape[0]
    pixel = pixel_at(placement, mouse.x, mouse.y, width, height)
    if pixel is not None:
        studio.state.inspector.hover = (f"{inspector.name}  view {studio.state.view + 1}  pixel {pixel[0]}, "
                                        f"{pixel[1]}  {inspector.readout(*pixel)}")


def _colorbar(inspector, colorbars, height: float) -> None:
    """The colour bar beside the last item, and the map's range under it."""
    if inspector.cmap:
        imgui.same_line(0, 2)
        imgui.image(colorbars[inspector.cmap].ref, imgui.ImVec2(BAR_WIDTH * imgui.get_style().font_scale_dpi,
                                                                  height))
        imgui.text_disabled(f"{inspector.lo:.3g} .. {inspector.hi:.3g}")


def _cell(studio, inspector, texture, width: float, height: float) -> None:
    """One inspector fitted into width x height points: name, image (a click enlarges it), colour
    bar, range."""
    imgui.begin_group()
    imgui.text(inspector.name)
    bar = BAR_WIDTH * imgui.get_style().font_scale_dpi if inspector.cmap else 0.0
    spacing = imgui.get_style().item_spacing.x
    image_width, image_height = texture.size
    fit = min((width - bar - 2 * spacing) / image_width, height / image_height)
    size = imgui.ImVec2(max(image_width * fit, 1), max(image_height * fit, 1))
    corner = imgui.get_cursor_screen_pos()
    if imgui.invisible_button(f"##{_label(inspector)}", size):
        studio.state.inspector.enlarge(inspector.slot)
    widgets.note(_label(inspector), "click: enlarge to the whole panel (zoom, pan, pixel readout)")
    far = imgui.ImVec2(corner.x + size.x, corner.y + size.y)
    imgui.get_window_draw_list().add_image(texture.ref, corner, far)
    middle = (corner.x + size.x / 2, corner.y + size.y / 2)
    _hover(studio, inspector, Placement(middle, ((image_width - 1) / 2, (image_height - 1) / 2), fit))
    _colorbar(inspector, studio.colorbars, size.y)
    if inspector.note:
        imgui.text_disabled(inspector.note)
    imgui.end_group()


def _enlarged(studio, inspector, texture) -> None:
    """An inspector over the whole panel: zoomed with the wheel about the mouse, panned by a
    drag, its pixels read out under the mouse."""
    zoom: ImageZoom = studio.state.inspector
    if widgets.button("all inspectors", "show every inspector side by side again", small=True):
        zoom.enlarge(None)
    imgui.same_line()
    if widgets.button("fit", "zoom out to the whole image", small=True):
        zoom.enlarge(zoom.enlarged)
    imgui.same_line()
    imgui.text(f"{inspector.name}  x{zoom.zoom:.3g}")
    imgui.same_line()
    imgui.text_disabled("wheel: zoom   drag: pan")
    avail, style = imgui.get_content_region_avail(), imgui.get_style()
    bar = BAR_WIDTH * style.font_scale_dpi + style.item_spacing.x if inspector.cmap else 0
    below = imgui.get_text_line_height_with_spacing() if inspector.cmap else 0  # the range
    size = imgui.ImVec2(max(avail.x - bar, 1), max(avail.y - below, 1))
    corner = imgui.get_cursor_screen_pos()
    area = (corner.x, corner.y, corner.x + size.x, corner.y + size.y)
    image = texture.size
    imgui.invisible_button(f"##{_label(inspector)} enlarged", size, DRAG_BUTTONS)
    widgets.note(f"{_label(inspector)} enlarged", "")
    io = imgui.get_io()
    if imgui.is_item_active() and (io.mouse_delta.x or io.mouse_delta.y):
        zoom.pan(io.mouse_delta.x, io.mouse_delta.y, image, area)
    if imgui.is_item_hovered() and io.mouse_wheel:
        zoom.zoom_at(io.mouse_wheel, io.mouse_pos.x, io.mouse_pos.y, image, area)
    placement = zoom.placement(image, area)
    low, high = placement.corners(*image)
    draw = imgui.get_window_draw_list()
    draw.push_clip_rect(imgui.ImVec2(area[0], area[1]), imgui.ImVec2(area[2], area[3]), True)
    draw.add_image(texture.ref, imgui.ImVec2(*low), imgui.ImVec2(*high))
    draw.pop_clip_rect()
    _hover(studio, inspector, placement)
    _colorbar(inspector, studio.colorbars, size.y)


def draw(studio, area: layout.Area) -> None:
    flags = imgui.WindowFlags_.no_scrollbar | imgui.WindowFlags_.no_scroll_with_mouse
    if layout.begin("Inspectors", area, flags):
        state, views = studio.state, len(studio.session.scene)
        imgui.set_next_item_width(12 * imgui.get_font_size())
        # Numbered from 1, as the keys 1 - 9 and the help count them.
        state.view = widgets.slider_int("training view", min(state.view, views - 1) + 1, 1, views,
                                        "the view the inspectors show (keys 1 - 9 pick the first nine)") - 1
        imgui.same_line()
        if widgets.button("Snap 3D view", "look through this view's camera in the 3D view"):
            state.request("snap")
        imgui.same_line()
        imgui.text_disabled(state.inspector.hover or "from the latest snapshot (click one to enlarge it)")
        state.inspector.hover = ""
        inspectors = studio.inspectors
        shown = [inspector.slot for inspector in inspectors]
        if not inspectors:
            imgui.text_disabled("computing...")
        elif state.inspector.enlarged in shown:
            index = shown.index(state.inspector.enlarged)
            _enlarged(studio, inspectors[index], studio.textures[index])
        else:
            avail = imgui.get_content_region_avail()
            cell = avail.x / len(INSPECTOR_NAMES)  # every slot, whether or not a run has started
            height = avail.y - 3 * imgui.get_text_line_height_with_spacing()
            start = imgui.get_cursor_pos_x()
            for i, (inspector, texture) in enumerate(zip(inspectors, studio.textures)):
                if i:
                    imgui.same_line(start + i * cell)
                _cell(studio, inspector, texture, cell, height)
    imgui.end()
