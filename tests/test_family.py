"""The procedural family of ABC-like parts: every design builds one valid, closed, manifold solid
with sharp edges, the designs differ, and the seed changes sizes, not designs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from edgedog.cli import main
from edgedog.groundtruth import ground_truth_for
from edgedog.synthetic.cad_file import check_solid
from edgedog.synthetic.family import BASES, DESIGNS, FEATURES, OTHERS, family_part, family_solid
from edgedog.synthetic.features import Arc, Traced
from edgedog.synthetic.sharp import sharp_curves


@pytest.mark.slow
def test_every_design_builds_a_valid_solid_with_sharp_edges(tmp_path):
    assert len(DESIGNS) >= 40 and len({recipe.name for recipe in DESIGNS}) == len(DESIGNS)
    kinds = set()
    for index, recipe in enumerate(DESIGNS):
        solid = family_solid(recipe, np.random.default_rng([index, 0]))
        assert len(solid.solids()) == 1, recipe.name
        check_solid(tmp_path / recipe.name, solid.wrapped, 1.0)  # valid, closed, manifold: or InputError
        curves = sharp_curves(solid)
        assert 4 <= len(curves) <= len(solid.edges()), recipe.name
        kinds |= {type(c).__name__ if not isinstance(c, Traced) else c.kind for c in curves}
        if "fillet" in recipe.features:  # the fillets' seams are edges, not sharp ones
            assert len(curves) < len(solid.edges())
    assert kinds == {"Line", "Arc", "ellipse", "bspline"}


def test_make_scene_family_writes_a_design_and_refuses_an_unknown_one(tmp_path, capsys):
    assert main(["make-scene", "--family", "36", "--out", str(tmp_path / "hub"), "--views", "3",
                 "--size", "64", "--detector", "canny"]) == 0
    manifest = json.loads((tmp_path / "hub" / "edgedog_scene.json").read_text())
    assert manifest["shape"] == DESIGNS[36].name == "flanged-hub"
    np.testing.assert_allclose(ground_truth_for(tmp_path / "hub").load(), family_part(36).ground_truth())
    assert main(["make-scene", "--family", str(len(DESIGNS)), "--out", str(tmp_path / "none")]) == 2
    assert f"the family's designs are 0 to {len(DESIGNS) - 1}" in capsys.readouterr().err
    assert not (tmp_path / "none").exists()
    with pytest.raises(SystemExit):
        main(["make-scene", "--help"])
    assert f"family of {len(DESIGNS)} ABC-like parts" in " ".join(capsys.readouterr().out.split())


def test_every_base_and_feature_is_used_and_the_seed_changes_sizes_only():
    used = {recipe.base for recipe in DESIGNS}
    assert used == set(BASES) | set(OTHERS)
    assert {name for recipe in DESIGNS for name in recipe.features} == set(FEATURES)
    first, again, other = family_part(0, 0), family_part(0, 0), family_part(0, 1)
    np.testing.assert_array_equal(first.ground_truth(), again.ground_truth())
    assert first.name == other.name and len(first.curves) == len(other.curves)
    assert not np.array_equal(first.ground_truth()[:10], other.ground_truth()[:10])
    corners = first.mesh.positions.reshape(-1, 3)
    assert np.isclose((corners.max(0) - corners.min(0)).max(), 1.0)
    assert any(isinstance(c, Arc) for c in first.curves)  # its small hole
