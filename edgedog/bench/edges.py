"""`edgedog bench edges`: each 2D detector's speed per megapixel on this CPU."""

from __future__ import annotations

import platform
import time
from pathlib import Path

import cv2
import numpy as np
import torch

from edgedog.builtin.scene import render_view
from edgedog.edges.registry import available_detectors, make_detector
from edgedog.synthetic.cameras import orbit_cameras


def bench_image(size: int) -> np.ndarray:
    """(size, size, 3) float32 RGB: a view of the built-in box on a textured background."""
    rgba, _ = render_view(orbit_cameras(7, size)[3])
    rng = np.random.default_rng(0)
    noise = cv2.GaussianBlur(rng.random((size, size)).astype(np.float32), (0, 0), 3.0)[..., None]
    alpha = rgba[..., 3:] / 255.0
    return (rgba[..., :3] / 255.0 * alpha + (0.3 + 0.4 * noise) * (1 - alpha)).astype(np.float32)


def run(size: int = 800, repeats: int = 3, weights: Path | None = None) -> dict:
    """Seconds per megapixel of every detector available (PiDiNet's NYUD and Multicue variants when
    their weights are given)."""
    names = available_detectors(weights)
    image = bench_image(size)
    megapixels = size * size / 1e6
    results = {}
    for name in names:
        detector = make_detector(name, weights)
        detector.detect(image)  # warm-up
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            detector.detect(image)
            times.append(time.perf_counter() - start)
        results[name] = {"seconds_per_view": round(float(np.median(times)), 4),
                         "seconds_per_megapixel": round(float(np.median(times)) / megapixels, 4)}
    return {"benchmark": "edges", "size": size, "repeats": repeats,
            "machine": {"cpu": platform.machine(), "torch_threads": torch.get_num_threads()},
            "detectors": results}


__all__ = ["bench_image", "run"]
