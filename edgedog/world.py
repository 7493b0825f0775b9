"""The bound on world coordinates that every input is checked against."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from edgedog.errors import InputError

MAX_COORDINATE = 1e6
"""Largest distance from the world origin, in scene units, of a camera or of an edge. Training
works in float32 (7 significant digits): a scene whose cameras lie farther out cannot resolve its
object (re-centre it), and a coordinate beyond it is broken (a pose of 1e30, an OBJ vertex of
1e300) or in other units."""


def check_coordinates(path: str | Path, *coordinates: np.ndarray) -> None:
    """InputError naming the file `path` when one of its `coordinates` (arrays of any shape, all
    finite) lies beyond MAX_COORDINATE."""
    largest = max((float(np.abs(part).max()) for part in coordinates if part.size), default=0.0)
    if largest > MAX_COORDINATE:
        raise InputError(path, f"holds a coordinate of {largest:.3g}, beyond the {MAX_COORDINATE:.0e} "
                               "units a scene may span")
