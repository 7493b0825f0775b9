"""Lazy loading of the compiled extension `edgedog.renderer._C`, which registers the rasterizer's
ops (`torch.ops.edgedog.*`) and their CPU kernels."""

from __future__ import annotations

import functools
import importlib
from types import ModuleType

from edgedog.errors import EdgeDogError

BUILD_HINT = (
    "build it with `make build` in the repository "
    "(or `pip install --no-build-isolation -e .` inside the virtual environment)"
)


class ExtensionNotBuiltError(EdgeDogError):
    """The C++ extension is missing or cannot be loaded."""


@functools.cache
def load_extension() -> ModuleType:
    """Import the compiled extension once, set the allocator up for rendering, return it.

    The allocator setting (glibc keeps blocks up to 256 MiB on its heap, see
    csrc/bindings.cpp) is process-wide: made here, when the kernels are first needed, rather
    than as a side effect of importing the module.

    Raises:
        ExtensionNotBuiltError: with a one-line message saying how to build it.
    """
    import torch  # noqa: F401  (the extension links against libtorch: load it first)

    try:
        extension = importlib.import_module("edgedog.renderer._C")
    except ImportError as exc:
        raise ExtensionNotBuiltError(
            f"the C++ extension edgedog.renderer._C is not built ({exc}); {BUILD_HINT}"
        ) from None
    extension.tune_allocator()
    return extension
