"""The studio window: a ModernGL context in the GLFW window and imgui-bundle's GLFW + OpenGL 3
backends, all on the main thread, and the frame loop around `Studio.frame`.
"""

from __future__ import annotations

import ctypes
import os
import time
from pathlib import Path

# imgui_bundle before glfw: it points glfw at the GLFW library it ships.
from imgui_bundle import imgui, implot  # isort: skip
import cv2
import glfw
import moderngl
import numpy as np
from edgedog.app import layout
from edgedog.app.display import InputWatch, init_glfw, open_window, scale_for_dpi
from edgedog.app.redraw import Rect, Redraw, aligned, clip_rects, clip_to, pixel_box
from edgedog.app.script import ScriptDriver
from edgedog.app.session import Session
from edgedog.app.studio import Studio
from edgedog.renderer.gl.context import GL_VERSION, window_context

ACTIVE_FPS, TRAINING_FPS, IDLE_FPS, TRAINING_IDLE_FPS = 30, 12, 2, 10
"""Frame rates while the user interacts (TRAINING_FPS when a run trains meanwhile: on a shared
2-core machine, orbiting at 20 a second left the training under half its headless rate, at 12
one half to two thirds), and otherwise (TRAINING_IDLE_FPS while a run trains: its snapshots and
readouts show within a tenth of a second). A frame is built at each (cheap), but drawn only when
it differs from the one shown (redraw.py; with EDGEDOG_STUDIO_PARTIAL=1 and a software OpenGL
only where it differs, the 3D view alone while orbiting): with a software OpenGL drawing costs
tens of milliseconds of CPU, which training needs. Input wakes the loop at once, and a key or a typed
character is drawn in the very next frame (python -m edgedog.bench.studio measures the rates and
how soon keys are drawn)."""


def save_screenshot(ctx: moderngl.Context, path: Path, width: int, height: int) -> Path:
    """The window's back buffer (the frame just drawn) as a PNG."""
    pixels = np.frombuffer(ctx.screen.read(viewport=(0, 0, width, height), components=3), np.uint8)
    image = pixels.reshape(height, width, 3)[::-1, :, ::-1]  # bottom-up RGB -> top-down BGR
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), image):
        raise OSError(f"{path}: cannot write the screenshot")
    return path


PARTIAL_REDRAW = os.environ.get("EDGEDOG_STUDIO_PARTIAL") == "1"
"""Draw only the region that changed with a software OpenGL (redraw.py): off unless
EDGEDOG_STUDIO_PARTIAL=1, while a one-pixel column at a panel's edge can keep an older colour
after a focus change (tests/test_studio_window.py::test_help_opens_in_the_same_place_each_time
fails with it on)."""
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast")
"""GL renderers that draw on the CPU: their back buffer is a plain image that keeps the frame
after a swap, so that a frame only draws the region that changed (redraw.py)."""


def software_gl(ctx: moderngl.Context) -> bool:
    """Whether the context draws on the CPU (Mesa's llvmpipe, softpipe or swrast)."""
    renderer = str(ctx.info.get("GL_RENDERER", "")).lower()
    return any(name in renderer for name in SOFTWARE_RENDERERS)


def _loop(window, ctx: moderngl.Context, studio: Studio, driver: ScriptDriver | None, watch: InputWatch
          ) -> None:
    title, redraw = None, Redraw(partial=PARTIAL_REDRAW and software_gl(ctx))
    # The window was exposed (uncovered, restored): its content is drawn again, whole.
    glfw.set_window_refresh_callback(window, lambda _window: redraw.invalidate())
    while not glfw.window_should_close(window):
        started = time.perf_counter()
        glfw.poll_events()
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()
        if driver is not None:  # after the backend's input: the script's clicks and keys come last
            driver.tick(studio)
            if driver.sent_input:
                watch.touch()
        imgui.new_frame()
        requests = studio.frame()
        imgui.render()
        changed = redraw.needed(imgui.get_draw_data(), studio.pictures)
        if changed or requests:  # a screenshot of an unchanged frame: the back buffer holds it, if kept
            _draw(window, ctx, requests, redraw.region if changed or redraw.partial else None, changed)
            studio.frames_drawn += 1
            watch.frame_drawn()
        if studio.title != title:
            title = studio.title
            glfw.set_window_title(window, title)
        idle = TRAINING_IDLE_FPS if studio.training else IDLE_FPS
        _wait_for_next_frame(watch, TRAINING_FPS if studio.training else ACTIVE_FPS, idle, started)


def _draw(window, ctx: moderngl.Context, requests: list, region: Rect | None = None,
          changed: bool = True) -> None:
    """Draw imgui's frame (only `region` of it, in display coordinates, when given: the back
    buffer holds the rest from the frame shown; nothing when not `changed`), act on the requests
    only the window can (screenshots of this frame, closing), and show the frame."""
    width, height = glfw.get_framebuffer_size(window)
    ctx.screen.viewport = (0, 0, width, height)
    ctx.screen.use()
    draw_data = imgui.get_draw_data()
    if region is None:
        ctx.screen.clear(*layout.background())
        imgui.backends.opengl3_render_draw_data(draw_data)
    elif changed:
        region = aligned(region, draw_data)
        clip_to(draw_data, region, clip_rects(draw_data))
        ctx.screen.clear(*layout.background(), viewport=pixel_box(region, draw_data, height))
        imgui.backends.opengl3_render_draw_data(draw_data)
    for request in requests:
        if request.name == "screenshot":
            save_screenshot(ctx, Path(request.args["path"]), width, height)
        elif request.name == "close":
            glfw.set_window_should_close(window, True)
    glfw.swap_buffers(window)


def _wait_for_next_frame(watch: InputWatch, cap: float, idle: float, started: float) -> None:
    """Wait until the frame begun at `started` has lasted 1 / `cap` s while the user interacts,
    1 / `idle` otherwise; a key or a typed character ends the wait at once (drawn in the next
    frame), other input only makes the window count as in use."""
    keys = watch.keys
    while watch.keys == keys:
        remaining = 1 / (cap if watch.active else idle) - (time.perf_counter() - started)
        if remaining <= 0:
            return
        glfw.wait_events_timeout(remaining)


def _ask_to_quit(window, studio: Studio) -> None:
    """The window's close button: a quit as q's (asked first while a run is under way)."""
    glfw.set_window_should_close(window, False)
    studio.state.request("quit")


def run_studio(session: Session, runs_root: Path | None = None, script: Path | None = None,
               size: tuple[int, int] = (1600, 1000), opening: Path | None = None) -> int:
    """Open the window on `session` and run until it is closed; returns the exit status (1 when
    a script failed). Closing stops training within a second. `opening`: a folder then opened as
    Open... opens it (`edgedog studio PHOTOS`: structure from motion is offered)."""
    driver = ScriptDriver.load(script) if script is not None else None
    init_glfw()
    try:
        window = open_window(*size)
        ctx = window_context()
        imgui.create_context()
        implot.create_context()
        imgui.get_io().set_ini_filename(None)  # the layout is fixed: nothing to remember
        scale_for_dpi(window)
        watch = InputWatch(window)
        imgui.backends.glfw_init_for_opengl(ctypes.cast(window, ctypes.c_void_p).value, True)
        imgui.backends.opengl3_init(f"#version {GL_VERSION}")
        studio = Studio(ctx, session, runs_root)
        studio.typed_drawn = watch.drawn
        if opening is not None:
            studio.state.request("open", path=str(opening))
        glfw.set_drop_callback(window, lambda _window, paths: studio.state.request("open", path=paths[0]))
        glfw.set_window_close_callback(window, lambda _window: _ask_to_quit(window, studio))
        try:
            _loop(window, ctx, studio, driver, watch)
        finally:
            glfw.hide_window(window)  # closed at once for the user, whatever the run needs to stop
            studio.close()
            imgui.backends.opengl3_shutdown()
            imgui.backends.glfw_shutdown()
            implot.destroy_context()
            imgui.destroy_context()
            ctx.release()
        if driver is not None:
            driver.write_report(studio)
            return 0 if driver.failure is None and driver.finished else 1
        return 0
    finally:
        glfw.terminate()
