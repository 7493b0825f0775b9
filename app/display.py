"""GLFW for the studio: the display check, the window with its OpenGL 3.3 core context, the
DPI scale, and when the user last touched the window. Light to import, so that a missing
display is reported before anything heavy loads.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import time

# imgui_bundle before glfw: it points glfw at the GLFW library it ships.
from imgui_bundle import imgui  # isort: skip
import glfw
from edgedog.app import MIN_SIZE
from edgedog.renderer.gl.context import GL_VERSION

from edgedog.errors import EdgeDogError

TITLE = "EdgeDoG Studio"
ACTIVE_SECONDS = 0.5
"""The window counts as in use this long after the last input (imgui settles hovers)."""


class NoDisplayError(EdgeDogError):
    """No window can be opened here (no display, or no OpenGL 3.3 core context)."""


def _no_window(reason: str) -> NoDisplayError:
    return NoDisplayError(f"studio: cannot open a window ({reason}); train headless instead: "
                          "edgedog train SCENE --out RUN")


def init_glfw() -> None:
    """Initialise GLFW, or raise NoDisplayError naming why not (GLFW's own message)."""
    errors: list[str] = []
    glfw.set_error_callback(lambda code, text: errors.append(text.decode(errors="replace")))
    if not glfw.init():
        raise _no_window(errors[-1] if errors else "GLFW cannot start")


def release_egl_thread() -> None:
    """Leave no EGL context current on this thread.

    glcontext's `release()` of a standalone EGL context (e.g. those that rendered the built-in
    scene on first use) destroys it but leaves it current, and libglvnd then refuses any GLX
    context on the same thread: GLFW's glXMakeCurrent fails with BadAccess and Xlib exits.
    """
    name = ctypes.util.find_library("EGL")
    if name is None:
        return  # no EGL here: nothing can be current
    egl = ctypes.CDLL(name)
    egl.eglGetCurrentContext.restype = egl.eglGetCurrentDisplay.restype = ctypes.c_void_p
    if egl.eglGetCurrentContext():
        egl.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
        egl.eglMakeCurrent(egl.eglGetCurrentDisplay(), None, None, None)


def open_window(width: int, height: int):
    """A window of `width` x `height` screen coordinates with a current OpenGL 3.3 core context
    (GLFW must be initialised)."""
    release_egl_thread()
    hints = ((glfw.CONTEXT_VERSION_MAJOR, GL_VERSION // 100),
             (glfw.CONTEXT_VERSION_MINOR, GL_VERSION // 10 % 10),
             (glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE), (glfw.OPENGL_FORWARD_COMPAT, True),
             (glfw.SCALE_TO_MONITOR, True))
    for hint, value in hints:
        glfw.window_hint(hint, value)
    window = glfw.create_window(width, height, TITLE, None, None)
    if not window:
        raise _no_window(f"no OpenGL {GL_VERSION / 100:.1f} core context")
    glfw.set_window_size_limits(window, *MIN_SIZE, glfw.DONT_CARE, glfw.DONT_CARE)
    glfw.make_context_current(window)
    glfw.swap_interval(1)
    return window


def scale_for_dpi(window) -> None:
    """Scale imgui's sizes and fonts by the monitor's content scale, less what the framebuffer
    already scales (macOS: window coordinates are points, the framebuffer has the pixels)."""
    content = max(glfw.get_window_content_scale(window))
    window_width = glfw.get_window_size(window)[0]
    pixels_per_point = glfw.get_framebuffer_size(window)[0] / window_width if window_width else 1.0
    scale = content / pixels_per_point
    style = imgui.get_style()
    style.scale_all_sizes(scale)
    style.font_scale_dpi = scale


class InputWatch:
    """When the user last touched the window, and when what they typed was drawn. Installed
    before imgui's backend, which chains these callbacks after its own.

    Attributes:
        keys: key presses and typed characters so far (the frame loop draws at once when it grows);
        typed: characters typed so far; drawn: (time.monotonic(), typed) after each frame that
            showed newly typed characters (the studio benchmark's input latency).
    """

    def __init__(self, window):
        self.last = time.perf_counter()
        self.keys = self.typed = 0
        self.drawn: list[tuple[float, int]] = []
        for install in (glfw.set_cursor_pos_callback, glfw.set_mouse_button_callback,
                        glfw.set_scroll_callback, glfw.set_window_size_callback,
                        glfw.set_window_focus_callback):
            install(window, self.touch)
        glfw.set_key_callback(window, self._key)
        glfw.set_char_callback(window, self._char)

    def touch(self, *_event) -> None:
        """Count as input now (also for input that does not come through GLFW: a script's)."""
        self.last = time.perf_counter()

    def _key(self, _window, _key, _scancode, action, _mods) -> None:
        if action != glfw.RELEASE:
            self.keys += 1
        self.touch()

    def _char(self, *_event) -> None:
        self.typed += 1
        self.keys += 1
        self.touch()

    def frame_drawn(self) -> None:
        """Note a frame shown (after the buffer swap) when characters were typed since the last."""
        if self.typed != (self.drawn[-1][1] if self.drawn else 0):
            self.drawn.append((time.monotonic(), self.typed))

    @property
    def active(self) -> bool:
        return time.perf_counter() - self.last < ACTIVE_SECONDS
