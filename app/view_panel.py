"""The 3D view panel: the View3D target as an image, orbited, panned and zoomed with the mouse."""

from __future__ import annotations

from edgedog.app import layout, widgets
from edgedog.app.textures import texture_ref
from edgedog.app.view3d import View3D
from imgui_bundle import imgui

VIEW_BUTTONS = (imgui.ButtonFlags_.mouse_button_left | imgui.ButtonFlags_.mouse_button_right
                | imgui.ButtonFlags_.mouse_button_middle)
HELP = "drag: orbit   right/middle or shift drag: pan   wheel: zoom"


def _mouse(view: View3D, scale: imgui.ImVec2) -> None:
    """Gestures on the last item (the view's invisible button), in framebuffer pixels."""
    io = imgui.get_io()
    if imgui.is_item_active():
        dx, dy = io.mouse_delta.x * scale.x, io.mouse_delta.y * scale.y
        if dx or dy:
            if imgui.is_mouse_down(imgui.MouseButton_.left) and not io.key_shift:
                view.orbit(dx, dy)
            else:
                view.pan(dx, dy)
    if imgui.is_item_hovered() and io.mouse_wheel:
        view.zoom(io.mouse_wheel)


def draw(studio, area: layout.Area) -> None:
    view = studio.view
    imgui.push_style_var(imgui.StyleVar_.window_padding, imgui.ImVec2(0, 0))
    flags = imgui.WindowFlags_.no_scrollbar | imgui.WindowFlags_.no_scroll_with_mouse
    if layout.begin("3D view", area, flags):
        size = imgui.get_content_region_avail()
        if size.x >= 1 and size.y >= 1:
            scale = imgui.get_io().display_framebuffer_scale  # HiDPI: pixels per point
            view.resize(round(size.x * scale.x), round(size.y * scale.y))
            origin = imgui.get_cursor_screen_pos()
            imgui.set_next_item_allow_overlap()  # the buttons drawn over the view get their clicks
            imgui.invisible_button("##view3d", size, VIEW_BUTTONS)
            widgets.RECTS["3D view"] = (origin.x, origin.y, origin.x + size.x, origin.y + size.y)
            _mouse(view, scale)
            view.render()
            corner = imgui.ImVec2(origin.x + size.x, origin.y + size.y)
            # The target's row 0 is the bottom of the picture: flip it.
            imgui.get_window_draw_list().add_image(texture_ref(view.texture), origin, corner,
                                                   imgui.ImVec2(0, 1), imgui.ImVec2(1, 0))
            padding = imgui.get_style().item_spacing
            imgui.set_cursor_screen_pos(imgui.ImVec2(origin.x + padding.x, origin.y + padding.y))
            imgui.text(f"{view.drawn} splats drawn")
            imgui.same_line()
            if widgets.button("reset view", "look at the scene from the side, as at the start (r)",
                              small=True):
                studio.state.request("reset_view")
            imgui.text_disabled(HELP)
    imgui.end()
    imgui.pop_style_var()
