"""`edgedog make-scene --abc MESH FEATURES`: an ABC object as ABC distributes it, rendered with its
own normals, with the protocol's ground truth; bad files refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from edgedog.cli import main
from edgedog.groundtruth import abc_points_from_cad, ground_truth_for
from edgedog.scenes import load_scene
from tests.helpers.bad_inputs import Case, assert_fails_cleanly, cases_as_params
from tests.helpers.paths import shared_path

# A 4 x 2 x 1 box in raw units: corner i has bits (x, y, z) of (i & 1, i >> 1 & 1, i >> 2 & 1).
CORNERS = np.array([[4.0 * (i & 1), 2.0 * (i >> 1 & 1), 1.0 * (i >> 2 & 1)] for i in range(8)])
QUADS = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
NORMALS = [(0, 0, -1), (0, 0, 1), (0, -1, 0), (0, 1, 0), (-1, 0, 0), (1, 0, 0)]
EDGES = sorted({(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1})


def box_obj(triangles: bool = True) -> str:
    lines = [f"v {x} {y} {z}" for x, y, z in CORNERS] + [f"vn {x} {y} {z}" for x, y, z in NORMALS]
    for n, (a, b, c, d) in enumerate(QUADS, start=1):
        corners = [[a, b, c], [a, c, d]] if triangles else [[a, b, c, d]]
        lines += ["f " + " ".join(f"{v + 1}//{n}" for v in face) for face in corners]
    return "\n".join(lines) + "\n"


def box_features(sharp: bool = True) -> str:
    """The 12 box edges as ABC curves, all sharp but the first (or none)."""
    curves = [{"type": "Line", "sharp": sharp and k != 0, "vert_indices": list(edge)}
              for k, edge in enumerate(EDGES)]
    return json.dumps({"curves": curves, "surfaces": []})  # JSON is YAML


def write_box(folder: Path, obj: str | bytes | None = None, features: str | None = None) -> tuple[Path, Path]:
    obj = box_obj() if obj is None else obj
    mesh = folder / "00000001_mesh.obj"
    mesh.write_bytes(obj) if isinstance(obj, bytes) else mesh.write_text(obj)
    (folder / "00000001_features.yml").write_text(box_features() if features is None else features)
    return folder / "00000001_mesh.obj", folder / "00000001_features.yml"


def make_scene(mesh: Path, features: Path, out: Path) -> int:
    return main(["make-scene", "--abc", str(mesh), str(features), "--out", str(out), "--views", "4",
                 "--size", "96", "--detector", "exact"])


def test_an_abc_object_gets_the_protocols_ground_truth(tmp_path):
    mesh, features = write_box(tmp_path)
    assert make_scene(mesh, features, tmp_path / "box") == 0
    scene = load_scene(tmp_path / "box")
    points = ground_truth_for(scene.root).load()
    # The protocol, with the box's own bounding box as ABC-NEF's statistics (scale 1 / 4).
    stats = tmp_path / "stats.json"
    stats.write_text(json.dumps({"00000001": {"bbox": [0, 0, 0, 4, 2, 1, 4, 2, 1]}}))
    expected = abc_points_from_cad(mesh, features, stats, "00000001")
    # 11 sharp edges (the first, along x, is marked smooth), sampled every 0.005 raw units.
    lengths = [4.0] * 3 + [2.0] * 4 + [1.0] * 4
    assert len(points) == len(expected) == sum(int(length // 0.005) for length in lengths)
    np.testing.assert_allclose(points, expected, atol=1e-12)
    # Rendered with its normals: the exact edge maps draw the sharp edges it sees.
    for i in range(len(scene)):
        pixels, inside = scene.camera(i).pixels(points)
        edges = scene.load_edge_map(i)
        assert inside.all() and edges[pixels[:, 1], pixels[:, 0]].mean() > 10 * edges.mean()
        assert scene.load_mask(i).mean() > 0.03  # the box fills 4 % or more of each view


@pytest.mark.shared_data
@pytest.mark.slow
def test_abc_object_00000006_as_distributed_matches_abc_nef_ground_truth(tmp_path):
    gt = shared_path("abc_nef/00000006") / "gt"
    mesh, features = next(gt.glob("*.obj")), next(gt.glob("*features*.yml"))
    assert main(["make-scene", "--abc", str(mesh), str(features), "--out", str(tmp_path / "00000006"),
                 "--views", "2", "--size", "64", "--detector", "canny"]) == 0
    points = ground_truth_for(tmp_path / "00000006").load()
    expected = ground_truth_for(gt.parent).load()
    # The same samples; ABC-NEF normalised by a bounding box padded by 0.03 %: under 0.2 mm apart.
    assert points.shape == expected.shape
    assert np.abs(points - expected).max() < 0.0002


def abc_case(name: str, *words, obj: str | bytes | None = None, features: str | None = None,
             blame: str = "obj"):
    def build(folder: Path):
        mesh, feats = write_box(folder, obj, features)
        return (["make-scene", "--abc", mesh, feats, "--out", folder / "scene", "--views", "2", "--size",
                 "32", "--detector", "canny"], [str(mesh if blame == "obj" else feats), *words])
    return Case(name, build)


CASES = [
    abc_case("quads", "not a triangle", obj=box_obj(triangles=False)),
    abc_case("no-faces", "no faces", obj="v 0 0 0\nv 1 0 0\nv 0 1 0\n",
             features=json.dumps({"curves": [{"sharp": True, "vert_indices": [0, 1]}]})),
    abc_case("face-past-the-vertices", "vertex that is not there", obj=box_obj() + "f 1//1 2//1 99//1\n"),
    abc_case("binary-obj", "not a text OBJ", obj=b"\xff\xfe\x00binary"),
    abc_case("no-sharp-curve", "no sharp feature curves", features=box_features(sharp=False), blame="yml"),
    abc_case("not-features", "not an ABC features file", features="- just\n- a list\n", blame="yml"),
]


@pytest.mark.parametrize("case", cases_as_params(CASES))
def test_a_bad_abc_object_is_one_line_and_nothing_is_written(case, tmp_path):
    assert_fails_cleanly(case, tmp_path)
    assert not (tmp_path / "scene").exists()
