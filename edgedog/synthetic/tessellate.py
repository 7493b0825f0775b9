"""The CAD kernel's triangulation of a B-rep, as the renderer's mesh.

OpenCascade meshes each face on its own (through build123d), with the face's own surface
normals at the nodes: curved faces shade smoothly, and the faces meeting at an edge keep one
normal each, so edges stay crisp in the renders.
"""

from __future__ import annotations

import numpy as np
from build123d import Shape

from edgedog.synthetic.mesh import Mesh

DEFLECTION = 0.0005
"""Largest distance (world units: 0.5 mm on a normalised part) from a triangle to the surface."""
ANGULAR_DEFLECTION = np.radians(5.0)
"""Largest turn of the surface normal across one triangle."""


def tessellate(shape: Shape) -> Mesh:
    """The triangles of every face of `shape`, oriented outwards, with the surfaces' normals."""
    vertices, triangles, normals, _ = shape.tessellate_with_uvs(DEFLECTION, ANGULAR_DEFLECTION,
                                                                atlas_packing=False)
    corners = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    positions = np.array([tuple(v) for v in vertices], dtype=np.float64).reshape(-1, 3)
    unit = np.array([tuple(n) for n in normals], dtype=np.float64).reshape(-1, 3)
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    return Mesh(positions[corners], unit[corners])
