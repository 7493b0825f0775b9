"""A run's primitives as PLY files (written atomically)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from edgedog.curve_files import write_point_columns
from edgedog.curves.primitives import LAYER


def write_points(path: Path, means: np.ndarray) -> None:
    """(N, 3) centres as a point-cloud PLY (what `edgedog eval` scores until curves exist)."""
    write_point_columns(path, {"x": means[:, 0], "y": means[:, 1], "z": means[:, 2]})


def write_primitives(path: Path, snapshot) -> None:
    """Every primitive's activated parameters: position, scales, rotation, opacity, DoG k, and
    its layer when the snapshot has layers."""
    columns = {"x": snapshot.means[:, 0], "y": snapshot.means[:, 1], "z": snapshot.means[:, 2]}
    columns.update({f"scale_{i}": snapshot.scales[:, i] for i in range(3)})
    columns.update({f"rot_{i}": snapshot.quats[:, i] for i in range(4)})
    columns["opacity"] = snapshot.opacity
    columns.update({f"k_{i}": snapshot.k_raw[:, i] for i in range(2)})
    if snapshot.layers is not None:
        columns[LAYER] = snapshot.layers
    write_point_columns(path, columns)
