"""The bound on world coordinates that every input is checked against."""

MAX_COORDINATE = 1e6
"""Largest distance from the world origin, in scene units, of a camera or of an edge. Training
works in float32 (7 significant digits): a scene whose cameras lie farther out cannot resolve its
object (re-centre it), and a coordinate beyond it is broken (a pose of 1e30, an OBJ vertex of
1e300) or in other units."""
