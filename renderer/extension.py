"""Lazy loading of the compiled CPU kernels `edgedog.renderer._C`."""

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
    """Import the compiled extension once and return it.

    Raises:
        ExtensionNotBuiltError: with a one-line message saying how to build it.
    """
    import torch  # noqa: F401  (the extension links against libtorch: load it first)

    try:
        return importlib.import_module("edgedog.renderer._C")
    except ImportError as exc:
        raise ExtensionNotBuiltError(
            f"the C++ extension edgedog.renderer._C is not built ({exc}); {BUILD_HINT}"
        ) from None
