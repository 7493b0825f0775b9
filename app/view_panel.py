"""The 3D view panel: the View3D target as an image, orbited, panned and zoomed with the mouse; a
click (a press and release without a drag) picks the curve and the primitive under it."""

from __future__ import annotations

from edgedog.app import layout, widgets
from edgedog.app.picking import panel_pixel
from edgedog.app.state import FISHER
from edgedog.app.textures import texture_ref
from edgedog.app.view3d import View3D
from imgui_bundle import imgui

VIEW_BUTTONS = (imgui.ButtonFlags_.mouse_button_left | imgui.ButtonFlags_.mouse_button_right
                | imgui.ButtonFlags_.mouse_button_middle)
HELP = "click: pick a curve or splat   drag: orbit   right/middle or shift drag: pan   wheel: zoom"
CLICK_SLOP = 3.0
"""A press and release with the mouse moved at most this many points between is a click."""
TRAINING_VIEW_FPS, TRAINING_ORBIT_FPS = 12, 8
"""The 3D view's own rate while a run trains: at most this many renders a second, however fast
the window draws (its panels answer keys and text sooner; a software OpenGL's renders cost the
training CPU time); TRAINING_ORBIT_FPS while the camera moves (each render of a moving view
costs about 14 ms of CPU with a software OpenGL on 2 cores, at half resolution)."""


def _mouse(view: View3D, origin: imgui.ImVec2, scale: imgui.ImVec2, pressed: bool) -> None:
    """Gestures on the last item (the view's invisible button), in framebuffer pixels; `pressed`:
    the button was released over it this frame."""
    io = imgui.get_io()
    if pressed and io.mouse_drag_max_distance_sqr[0] <= CLICK_SLOP ** 2:
        view.pick(*panel_pixel((io.mouse_pos.x, io.mouse_pos.y), (origin.x, origin.y), (scale.x, scale.y)))
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
    # The picture covers the panel: no background drawn under it.
    flags = (imgui.WindowFlags_.no_scrollbar | imgui.WindowFlags_.no_scroll_with_mouse
             | imgui.WindowFlags_.no_background)
    if layout.begin("3D view", area, flags):
        size = imgui.get_content_region_avail()
        if size.x >= 1 and size.y >= 1:
            scale = imgui.get_io().display_framebuffer_scale  # HiDPI: pixels per point
            view.resize(round(size.x * scale.x), round(size.y * scale.y))
            origin = imgui.get_cursor_screen_pos()
            imgui.set_next_item_allow_overlap()  # the buttons drawn over the view get their clicks
            pressed = imgui.invisible_button("##view3d", size, VIEW_BUTTONS)
            widgets.RECTS["3D view"] = (origin.x, origin.y, origin.x + size.x, origin.y + size.y)
            _mouse(view, origin, scale, pressed and imgui.is_mouse_released(imgui.MouseButton_.left))
            rate = TRAINING_ORBIT_FPS if view.moving else TRAINING_VIEW_FPS
            view.render(1 / rate if studio.training else 0.0)
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
            imgui.push_text_wrap_pos(0.0)  # at the view's right edge
            imgui.text_disabled(HELP)
            _readout(studio)
            imgui.pop_text_wrap_pos()
    imgui.end()
    imgui.pop_style_var()


def _readout(studio) -> None:
    """The picked curve and primitive, and the state of the Fisher colouring."""
    view = studio.view
    if studio.state.display.color_by == FISHER:
        if view.fisher_error is not None:
            imgui.text_colored(imgui.ImVec4(1.0, 0.4, 0.3, 1.0), f"Fisher scores: {view.fisher_error}")
        elif view.color_range is None:
            imgui.text_disabled("Fisher U: computing the scores...")
        else:
            imgui.text_disabled(f"Fisher U (log10, low: uncertain) at step {view.fisher.step}")
    if view.picked is not None:
        for line in view.picked.lines:
            imgui.text(line)
