"""A run's primitives as PLY files (written atomically)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from edgedog.primitives import write_ply, write_point_columns


def write_points(path: Path, means: np.ndarray) -> None:
    """(N, 3) centres as a point-cloud PLY (what `edgedog eval` scores until curves exist)."""
    write_point_columns(path, {"x": means[:, 0], "y": means[:, 1], "z": means[:, 2]})


def write_primitives(path: Path, snapshot) -> None:
    """primitives.ply of a `Snapshot`: every primitive's activated parameters, its layer when the
    snapshot has layers, and b of a view-dependent opacity when it has one (edgedog.primitives)."""
    write_ply(path, snapshot.primitives)
