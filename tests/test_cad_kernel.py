"""The CAD kernel's ground truth: sharp edges of known solids, exact counts and lengths, the
sharpness rule on fillets, chamfers and bends, and curves that are neither lines nor circles."""

from __future__ import annotations

import build123d as bd
import numpy as np
import pytest

from edgedog.groundtruth import GT_SPACING
from edgedog.synthetic.brep import part_from_solid
from edgedog.synthetic.features import Arc, Line, Traced, sample_curve
from edgedog.synthetic.sharp import SHARP_ANGLE, sharp_curves

MIN = (bd.Align.MIN,) * 3


def lengths(curves) -> list[float]:
    return sorted(round(c.length, 9) for c in curves)


def test_a_box_with_a_pocket_has_its_24_edges_exactly():
    block = bd.Box(1.0, 0.8, 0.4, align=MIN)
    pocket = bd.Pos(0.3, 0.2, 0.2) * bd.Box(0.4, 0.3, 0.2, align=MIN)  # open at the top, 0.2 deep
    part = part_from_solid("pocketed", block - pocket, {})
    assert all(isinstance(c, Line) for c in part.curves)
    # The block's 12 edges; the pocket's rim (convex) and floor (concave) rectangles and its 4
    # concave vertical edges.
    expected = [1.0] * 4 + [0.8] * 4 + [0.4] * 4 + [0.4, 0.4, 0.3, 0.3] * 2 + [0.2] * 4
    assert lengths(part.curves) == sorted(expected)
    # Normalised like ABC: the longest side is already 1, so only moved to centre (0.5, 0.5, 0.5).
    lo, hi = part.mesh.positions.reshape(-1, 3).min(0), part.mesh.positions.reshape(-1, 3).max(0)
    np.testing.assert_allclose([lo, hi], [[0, 0.1, 0.3], [1, 0.9, 0.7]], atol=1e-12)
    floor = [c for c in part.curves if np.allclose([c.a[2], c.b[2]], 0.3 + 0.2)]
    assert len(floor) == 4  # the pocket's floor at z = 0.2 + 0.3
    # floor(length / spacing) per edge: 1 less where the kernel's length is a hair under the
    # decimal one (0.4 - 1e-17), as the protocol counts.
    points = part.ground_truth()
    assert len(points) == sum(int(c.length // GT_SPACING) for c in part.curves)
    assert 0 <= sum(length / GT_SPACING for length in expected) - len(points) <= len(expected)


def test_fillets_are_not_sharp_and_chamfers_are():
    block = bd.Box(1.0, 0.7, 0.5, align=MIN)
    assert sharp_curves(bd.fillet(block.edges(), 0.1)) == []  # every edge rounded: nothing sharp
    # Four vertical edges rounded: 8 quarter circles and 8 straight sides top and bottom; the 8
    # seams where the fillets meet the sides are tangent, not sharp.
    rounded = bd.fillet(block.edges().filter_by(bd.Axis.Z), 0.1)
    curves = sharp_curves(rounded)
    assert len(rounded.edges()) == 24 and len(curves) == 16
    arcs = [c for c in curves if isinstance(c, Arc)]
    assert len(arcs) == 8 and all(np.isclose(a.length, np.pi / 2 * 0.1) for a in arcs)
    assert not [c for c in curves if isinstance(c, Line) and not np.isclose(c.a[2], c.b[2])]
    # Every edge chamfered: the chamfers meet the sides at 45 degrees and the corner triangles
    # at 35: all 48 edges are sharp.
    cut = bd.chamfer(block.edges(), 0.1)
    assert len(cut.edges()) == 48 and len(sharp_curves(cut)) == 48


@pytest.mark.parametrize("bend, sharp", [(SHARP_ANGLE - 5, False), (SHARP_ANGLE + 5, True)])
def test_a_bend_is_sharp_beyond_the_threshold_only(bend, sharp):
    """A plate whose top face bends down by `bend` degrees halfway: only the fold line can tell."""
    drop = 0.5 * np.tan(np.radians(bend))
    profile = [(0, 0), (1, 0), (1, 0.3 - drop), (0.5, 0.3), (0, 0.3)]
    plate = bd.extrude(bd.Polygon(*profile, align=None), amount=0.4)
    fold = [c for c in sharp_curves(plate)
            if isinstance(c, Line) and np.allclose([c.a[:2], c.b[:2]], [0.5, 0.3])]
    assert len(fold) == int(sharp)
    assert len(sharp_curves(plate)) == 14 + int(sharp)  # two pentagons' 10 edges, 4 (or 5) across


def test_an_ellipse_is_traced_by_the_kernel_and_sampled_by_the_protocol():
    """A cylinder of radius 0.2 cut by a plane at 45 degrees: its top edge is an ellipse with
    semi-axes 0.2 and 0.2 * sqrt(2)."""
    cylinder = bd.Cylinder(0.2, 1.0, align=(bd.Align.CENTER, bd.Align.CENTER, bd.Align.MIN))
    cutter = bd.Pos(0, 0, 0.5) * bd.Rot(45, 0, 0) * bd.Box(2, 2, 2, align=(bd.Align.CENTER, bd.Align.CENTER,
                                                                          bd.Align.MIN))
    curves = sharp_curves(cylinder - cutter)
    (ellipse,) = [c for c in curves if isinstance(c, Traced)]
    assert ellipse.kind == "ellipse" and len([c for c in curves if isinstance(c, Arc)]) == 1
    a, b = 0.2 * np.sqrt(2), 0.2
    h = ((a - b) / (a + b)) ** 2
    perimeter = np.pi * (a + b) * (1 + 3 * h / (10 + np.sqrt(4 - 3 * h)))  # Ramanujan's, to 1e-9 here
    assert ellipse.length == pytest.approx(perimeter, rel=1e-6)
    samples = sample_curve(ellipse)
    assert len(samples) == int(ellipse.length // GT_SPACING)
    # On the cylinder and on the cutting plane, at equal steps along the curve.
    np.testing.assert_allclose(np.hypot(samples[:, 0], samples[:, 1]), 0.2, atol=1e-6)
    np.testing.assert_allclose(samples[:, 2] - 0.5, samples[:, 1] * np.tan(np.radians(45)), atol=1e-6)
    steps = np.linalg.norm(np.diff(samples, axis=0), axis=1)
    assert steps.max() - steps.min() < 1e-5
