"""A B-rep solid as a Part: normalised like an ABC object, triangulated for the renderer, and its
sharp edges as the exact ground-truth curves, all by the CAD kernel."""

from __future__ import annotations

import numpy as np
from build123d import Shape

from edgedog.synthetic.shapes import Part
from edgedog.synthetic.sharp import sharp_curves
from edgedog.synthetic.tessellate import tessellate


def bounds(shape: Shape) -> tuple[np.ndarray, np.ndarray]:
    """(3,) lowest and highest corners of the shape's exact (not tolerance-padded) bounding box."""
    box = shape.bounding_box(optimal=True)
    return np.array(tuple(box.min)), np.array(tuple(box.max))


def normalised(shape: Shape) -> tuple[Shape, float]:
    """`shape` scaled so that the longest side of its bounding box is 1 and centred at (0.5, 0.5,
    0.5), as ABC's ground truth frame puts an object; and that scale."""
    lo, hi = bounds(shape)
    scale = 1.0 / float((hi - lo).max())
    return shape.scale(scale, about=(0, 0, 0)).translate(tuple(0.5 - (lo + hi) / 2 * scale)), scale


def part_from_solid(name: str, solid: Shape, dimensions: dict[str, float], normalise: bool = True) -> Part:
    """The Part of `solid`, first normalised into [0, 1]^3 (`normalised`) unless `normalise` is
    False; `dimensions` (in the solid's units) are scaled with it."""
    scale = 1.0
    if normalise:
        solid, scale = normalised(solid)
    return Part(name, {k: round(v * scale, 6) for k, v in dimensions.items()}, tessellate(solid),
                tuple(sharp_curves(solid)), solid)
