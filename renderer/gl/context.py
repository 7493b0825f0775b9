"""OpenGL contexts for the renderer: a headless one through EGL, or the current window's.

The caller owns the context: release every renderer and target made in it first, then call
`ctx.release()`. moderngl issues every call to the context current on the calling thread;
creating a context makes it current (`with ctx:` switches between several).
"""

from __future__ import annotations

import moderngl

GL_VERSION = 330
"""OpenGL 3.3 core: instancing, integer attributes, texture arrays and float render targets."""


class GLUnavailableError(RuntimeError):
    """No OpenGL 3.3 core context could be created (no EGL library, driver or device)."""


def offscreen_context() -> moderngl.Context:
    """A standalone OpenGL context without a window or display (EGL; Mesa's llvmpipe on CPU)."""
    try:
        return moderngl.create_standalone_context(backend="egl", require=GL_VERSION)
    except Exception as error:  # glcontext raises a bare Exception for a missing library or device
        raise GLUnavailableError(f"cannot create a headless OpenGL {GL_VERSION / 100:.1f} context "
                                 f"through EGL: {error}") from error


def window_context() -> moderngl.Context:
    """The OpenGL context current on this thread (e.g. a GLFW window's), for drawing into it."""
    return moderngl.create_context(require=GL_VERSION)
