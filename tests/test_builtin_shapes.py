"""The built-in parts' geometry, without rendering: the kernel's closed meshes, exact curves,
seeded sizes."""

from __future__ import annotations

import numpy as np
import pytest

from edgedog.errors import ConfigError
from edgedog.groundtruth import GT_SPACING
from edgedog.metrics import sample_line
from edgedog.synthetic.designs import DESIGNS
from edgedog.synthetic.features import Arc, Line, sample_curve
from edgedog.synthetic.shapes import SHAPES, make_part


@pytest.mark.parametrize("name", SHAPES)
def test_every_part_is_a_closed_outward_mesh_normalised_like_abc(name):
    for seed in (0, 1):
        mesh = make_part(name, seed).mesh
        corners = mesh.positions.reshape(-1, 3)
        ids = np.unique(np.round(corners, 9), axis=0, return_inverse=True)[1].reshape(-1, 3)
        directed = np.concatenate([ids[:, [0, 1]], ids[:, [1, 2]], ids[:, [2, 0]]])
        # Closed and consistently oriented: every edge once each way (this also rules out
        # T-junctions, where a long edge would meet two shorter ones).
        forward = {tuple(e) for e in directed}
        assert len(forward) == len(directed) and {(b, a) for a, b in forward} == forward
        a, b, c = mesh.positions[:, 0], mesh.positions[:, 1], mesh.positions[:, 2]
        facet = np.cross(b - a, c - a)
        assert np.einsum("ij,ij->", a, np.cross(b, c)) > 0  # positive volume: normals point out
        facet /= np.linalg.norm(facet, axis=1, keepdims=True)
        # Corner normals follow their facets (curved faces within half the kernel's angular step).
        assert np.einsum("ti,tki->tk", facet, mesh.normals).min() > np.cos(np.radians(3))
        lo, hi = corners.min(0), corners.max(0)
        assert np.isclose((hi - lo).max(), 1.0) and np.allclose((lo + hi) / 2, 0.5)


@pytest.mark.parametrize("name", SHAPES)
def test_ground_truth_follows_the_protocol_along_each_curve(name):
    part = make_part(name, 2)
    points = part.ground_truth()
    assert len(points) == sum(int(c.length // GT_SPACING) for c in part.curves)
    assert points.min() >= -1e-9 and points.max() <= 1 + 1e-9
    for curve in part.curves:
        samples = sample_curve(curve)
        steps = np.linalg.norm(np.diff(samples, axis=0), axis=1)
        # Equal steps of at least the spacing and below twice of it (chords of arcs a bit shorter).
        assert np.allclose(steps, steps[0], rtol=1e-6) and GT_SPACING * 0.99 <= steps[0] < 2 * GT_SPACING
        if isinstance(curve, Line):
            np.testing.assert_allclose(samples, sample_line(curve.a, curve.b, GT_SPACING))


def test_sharp_edges_only_fillet_boundaries_are_not_features():
    def vertical_lines(part):
        return [c for c in part.curves if isinstance(c, Line) and abs(c.a[2] - c.b[2]) > 1e-9]

    filleted, chamfered, box = (make_part(n, 0) for n in ("filleted-block", "chamfered-block", "box"))
    # Fillets meet the flat sides tangentially: only their quarter circles at top and bottom.
    assert len(vertical_lines(filleted)) == 0
    arcs = [c for c in filleted.curves if isinstance(c, Arc)]
    assert len(arcs) == 8 and all(np.isclose(abs(a.stop - a.start), np.pi / 2) for a in arcs)
    # Chamfers are sharp on both sides: 8 vertical edges, 8 + 8 outline edges.
    assert len(vertical_lines(chamfered)) == 8 and len(chamfered.curves) == 24
    assert len(box.curves) == 12
    cylinder = make_part("cylinder", 0)
    assert len(cylinder.curves) == 2 and all(isinstance(c, Arc) for c in cylinder.curves)


def test_seeds_change_dimensions_and_holes():
    for name in SHAPES:
        first, again, other = make_part(name, 0), make_part(name, 0), make_part(name, 1)
        assert first.dimensions == again.dimensions
        np.testing.assert_array_equal(first.ground_truth(), again.ground_truth())
        assert first.dimensions != other.dimensions, name
    holes = [{k: v for k, v in make_part("plate-holes", seed).dimensions.items() if k.startswith("hole")}
             for seed in range(4)]
    assert len({tuple(sorted(h.items())) for h in holes}) == 4
    assert {len(h) // 3 for h in holes} <= {2, 3, 4}


def test_every_shape_has_a_design_and_parts_are_built_once():
    assert list(DESIGNS) == list(SHAPES)
    assert make_part("boss", 5) is make_part("boss", 5)


def test_unknown_shape_names_the_choices():
    with pytest.raises(ConfigError, match="unknown shape 'gear'; choose from box, l-bracket"):
        make_part("gear")
