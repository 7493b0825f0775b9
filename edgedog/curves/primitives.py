"""A run's trained primitives (`primitives.ply`) as edge points with directions."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from plyfile import PlyData

from edgedog.errors import InputError

_COLUMNS = ["x", "y", "z", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3", "opacity",
            "k_0", "k_1"]
UNCERTAINTY = "uncertainty"
"""Optional per-primitive score column carried through to edge_points.ply when a run has it."""
LAYER = "layer"
"""Optional column: the multi-granularity layer of each primitive (edgedog.train.layers)."""


@dataclass
class EdgePrimitives:
    """Primitives as oriented edge points.

    points: (N, 3) centres; directions: (N, 3) unit axes of the largest scale; elongation: (N,)
    largest / middle scale; opacity: (N,); k: (N, 2) DoG shape; uncertainty: (N,) or None;
    layers: (N,) int64 layer index or None (a single-layer run).
    """

    points: np.ndarray
    directions: np.ndarray
    elongation: np.ndarray
    opacity: np.ndarray
    k: np.ndarray
    uncertainty: np.ndarray | None = None
    layers: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, keep: np.ndarray) -> EdgePrimitives:
        """The primitives selected by a (N,) bool mask or an index array."""
        return EdgePrimitives(self.points[keep], self.directions[keep], self.elongation[keep],
                              self.opacity[keep], self.k[keep],
                              None if self.uncertainty is None else self.uncertainty[keep],
                              None if self.layers is None else self.layers[keep])

    def in_layers(self, layers: set[int]) -> EdgePrimitives:
        """The primitives of the given layers (a run without layers has everything in layer 0)."""
        own = np.zeros(len(self), np.int64) if self.layers is None else self.layers
        return self.subset(np.isin(own, sorted(layers)))


def quaternion_axes(quats: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of quaternions (N, 4) (w, x, y, z, any non-zero norm)."""
    w, x, y, z = (quats / np.linalg.norm(quats, axis=1, keepdims=True)).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)


def read_primitives(path: str | Path) -> EdgePrimitives:
    """Read `primitives.ply` as written by `edgedog train` (activated scales and opacity)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "no such file (is this a run folder written by `edgedog train`?)")
    try:
        vertex = PlyData.read(str(path))["vertex"]
    except Exception as exc:  # plyfile raises many types on malformed files
        raise InputError(path, f"not a readable PLY file with a vertex element ({exc})") from None
    names = set(vertex.data.dtype.names)
    missing = [k for k in _COLUMNS if k not in names]
    if missing:
        raise InputError(path, f"not a primitives PLY: no vertex properties {', '.join(missing)}")

    def columns(keys: list[str]) -> np.ndarray:
        return np.stack([vertex[k] for k in keys], axis=1).astype(np.float64)

    points, scales, quats = columns(_COLUMNS[:3]), columns(_COLUMNS[3:6]), columns(_COLUMNS[6:10])
    opacity, k = columns(["opacity"])[:, 0], columns(["k_0", "k_1"])
    uncertainty = columns([UNCERTAINTY])[:, 0] if UNCERTAINTY in names else None
    layers = np.rint(columns([LAYER])[:, 0]).astype(np.int64) if LAYER in names else None
    if not np.all(np.isfinite(np.hstack([points, scales, quats]))) or np.any(np.all(quats == 0, axis=1)):
        raise InputError(path, "primitives contain NaN, infinite values or zero quaternions")
    largest = np.argmax(scales, axis=1)
    directions = quaternion_axes(quats)[np.arange(len(points)), :, largest]
    ordered = np.sort(scales, axis=1)
    elongation = ordered[:, 2] / np.maximum(ordered[:, 1], 1e-12)
    return EdgePrimitives(points, directions, elongation, opacity, k, uncertainty, layers)
