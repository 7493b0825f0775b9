"""edgedog.renderer: the differentiable DoG rasterizer (ops registered per device, with the
C++ CPU kernels of csrc/, behind autograd wrappers; and a pure-torch reference) and the ModernGL
splat and line renderer.

The compiled kernels load on first use through :func:`load_extension`; importing this package
never compiles or loads anything.
"""

from edgedog.renderer.extension import ExtensionNotBuiltError, load_extension

__all__ = ["ExtensionNotBuiltError", "load_extension"]
