"""A run's primitives as PLY files (written atomically)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement

from edgedog.files import atomic_write


def _write(path: Path, columns: dict[str, np.ndarray]) -> None:
    n = len(next(iter(columns.values())))
    rows = np.empty(n, dtype=[(name, "f4") for name in columns])
    for name, values in columns.items():
        rows[name] = values
    atomic_write(path, PlyData([PlyElement.describe(rows, "vertex")]).write)


def write_points(path: Path, means: np.ndarray) -> None:
    """(N, 3) centres as a point-cloud PLY (what `edgedog eval` scores until curves exist)."""
    _write(path, {"x": means[:, 0], "y": means[:, 1], "z": means[:, 2]})


def write_primitives(path: Path, snapshot) -> None:
    """Every primitive's activated parameters: position, scales, rotation, opacity, DoG k."""
    columns = {"x": snapshot.means[:, 0], "y": snapshot.means[:, 1], "z": snapshot.means[:, 2]}
    columns.update({f"scale_{i}": snapshot.scales[:, i] for i in range(3)})
    columns.update({f"rot_{i}": snapshot.quats[:, i] for i in range(4)})
    columns["opacity"] = snapshot.opacity
    columns.update({f"k_{i}": snapshot.k_raw[:, i] for i in range(2)})
    _write(path, columns)
