"""The catalogue of built-in CAD parts and the Part they become: a solid of the CAD kernel,
its triangle mesh and its exact sharp edges.

Each part is modelled by `designs` with seeded dimensions and normalised like an ABC object:
scaled so that the longest side of its bounding box is 1 and centred at (0.5, 0.5, 0.5), the
ground-truth frame, where the protocol's spacing (GT_SPACING) is 5 mm. This module imports no
CAD kernel (the command line lists the shapes without loading it); `make_part` does.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from edgedog.errors import ConfigError
from edgedog.groundtruth import GT_SPACING
from edgedog.synthetic.features import Curve, sample_curves
from edgedog.synthetic.mesh import Mesh


@dataclass(frozen=True)
class Part:
    """A part in the ground-truth frame.

    Attributes:
        name: the shape's name (or the CAD file's).
        dimensions: its sizes (and positions from the part's corner), in ground-truth units
            (1 = 1000 mm).
        mesh: the kernel's triangulation of its faces.
        curves: its sharp edges (`edgedog.synthetic.sharp`), exact.
        solid: the kernel's solid (a build123d Shape) they come from; None for a mesh.
        spacing: the ground truth's sampling step along the curves: GT_SPACING, except for an
            ABC object, whose protocol samples every 0.005 of its raw units (`edgedog.synthetic.abc_file`).
    """

    name: str
    dimensions: dict[str, float]
    mesh: Mesh
    curves: tuple[Curve, ...]
    solid: object
    spacing: float = GT_SPACING

    def ground_truth(self) -> np.ndarray:
        """(N, 3) the curves sampled by the ABC protocol."""
        return sample_curves(self.curves, self.spacing)


SHAPES = {
    "box": "rectangular block",
    "l-bracket": "L-shaped angle bracket",
    "plate-holes": "plate with 2 to 4 round through holes",
    "stepped-block": "staircase block of 2 or 3 steps",
    "cylinder": "round cylinder",
    "chamfered-block": "block with chamfered vertical edges",
    "filleted-block": "block with filleted vertical edges",
    "boss": "block with a cylindrical boss on top",
}
"""Name -> description of the parts `make_part` builds."""


@functools.lru_cache(maxsize=32)
def make_part(name: str, seed: int = 0) -> Part:
    """The part `name` with dimensions drawn from `seed` (built once per process: callers share
    it and must not change its arrays)."""
    if name not in SHAPES:
        raise ConfigError(f"unknown shape {name!r}; choose from {', '.join(SHAPES)}")
    from edgedog.synthetic.brep import part_from_solid  # the CAD kernel: seconds to import
    from edgedog.synthetic.designs import DESIGNS

    solid, dimensions = DESIGNS[name](np.random.default_rng(seed))
    return part_from_solid(name, solid, dimensions)
