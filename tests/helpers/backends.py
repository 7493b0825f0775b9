"""The backend-parity harness: the rasterizer's kernel tests run on every device with kernels.

A backend is a device with a kernel for each of the renderer's ops (`ops.kernel_devices()`):
the C++ kernels on "cpu" today, "cuda" once the extension registers CUDA kernels and a GPU is
present. A kernel test marked `@each_device` takes a `device` argument, renders on it and
brings the results back to the CPU, where the float64 torch reference stays the ground truth:
every backend meets the same expectations and tolerances.
"""

from __future__ import annotations

import pytest
import torch
from edgedog.renderer.ops import kernel_devices
from edgedog.renderer.primitives import Primitives

PARAMS = ("means", "log_scales", "quats", "opacity_logits", "k_raw", "colors")

KERNEL_DEVICES = kernel_devices()
each_device = pytest.mark.parametrize("device", KERNEL_DEVICES)
"""Runs a test once per backend, with its device name as the `device` argument."""


def on_device(prims: Primitives, device: str, dtype: torch.dtype | None = None,
              leaves: bool = False) -> Primitives:
    """Copies of the primitives' tensors on `device` (in `dtype` if given); leaves that require
    gradients when `leaves`."""
    def copy(tensor: torch.Tensor) -> torch.Tensor:
        moved = tensor.detach().to(device=device, dtype=dtype or tensor.dtype)
        return moved.clone().requires_grad_(True) if leaves else moved
    return Primitives(*(copy(getattr(prims, k)) for k in PARAMS))
