"""`edgedog eval --per-curve --figure`: the picture of the diagnosis shows the views that see the
missed curves, drawn in the missed colour where the curve is; its options fail in one line."""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.image import imread

from edgedog.cli import main
from edgedog.diagnosis_figure import MISSED, choose_views
from edgedog.scenes import load_scene
from edgedog.synthetic.shapes import make_part
from tests.test_per_curve import REMOVED, _write_run


def test_choose_views_takes_the_view_that_adds_most_each_time():
    seen = np.array([[1, 1, 0, 0, 0],
                     [1, 1, 1, 0, 0],
                     [0, 0, 0, 1, 1],
                     [0, 0, 0, 0, 0]], bool)
    assert choose_views(seen, 2) == [1, 2]
    assert choose_views(seen, 4) == [1, 2]  # no view adds anything after those two
    assert choose_views(np.zeros((3, 4), bool), 2) == [0]


def _missed_colour_near(picture: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels within a few levels of the missed colour."""
    target = np.array([int(MISSED[i:i + 2], 16) / 255 for i in (1, 3, 5)])
    return (np.abs(picture[..., :3] - target) < 0.08).all(axis=2)


def test_the_figure_shows_the_missed_curve_in_views_that_see_it(bracket_scene, tmp_path, capsys):
    run = _write_run(tmp_path / "run", bracket_scene, drop_primitives=True)
    figure = tmp_path / "missed.png"
    assert main(["eval", str(run), "--scene", str(bracket_scene), "--per-curve", "--json",
                 str(tmp_path / "e.json"), "--figure", str(figure), "--figure-views", "2"]) == 0
    out = capsys.readouterr().out
    views = [int(v) for v in out.split("figure written to")[1].split("(views ")[1].split(")")[0].split(", ")]
    assert len(views) == 1  # the first view sees the whole removed curve: a second adds nothing
    picture = imread(figure)
    assert picture.shape[:2] == (600, 500)  # one panel
    assert _missed_colour_near(picture).sum() > 50  # the missed curve, drawn
    # each view shown sees the removed curve (its middle in the view's image, on the part)
    scene = load_scene(bracket_scene)
    curve = make_part("l-bracket").curves[REMOVED]
    middle = (np.asarray(curve.a) + np.asarray(curve.b)) / 2
    gt_to_world = np.linalg.inv(scene.world_to_gt)
    world = middle @ gt_to_world[:3, :3].T + gt_to_world[:3, 3]
    for view in views:
        assert scene.camera(view).pixels(world[None])[1][0]
    assert json.loads((tmp_path / "e.json").read_text())["per_curve"]["curves"][REMOVED]["missed"]


@pytest.mark.parametrize("extra, message", [
    (["--figure", "x.png"], "add --per-curve"),
    (["--per-curve", "--figure", "x.jpg"], "name a .png file"),
])
def test_figure_options_fail_in_one_line(bracket_scene, tmp_path, capsys, extra, message):
    run = _write_run(tmp_path / "run", bracket_scene, drop_primitives=True)
    args = ["eval", str(run), "--scene", str(bracket_scene), "--json", str(tmp_path / "e.json")]
    assert main(args + [a if not a.startswith("x.") else str(tmp_path / a) for a in extra]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and message in error
    assert not (tmp_path / "e.json").exists()


def test_the_figure_is_never_written_inside_the_scene(bracket_scene, tmp_path, capsys):
    run = _write_run(tmp_path / "run", bracket_scene, drop_primitives=True)
    inside = bracket_scene / "missed.png"
    assert main(["eval", str(run), "--scene", str(bracket_scene), "--per-curve", "--json",
                 str(tmp_path / "e.json"), "--figure", str(inside)]) != 0
    assert "scene folder" in capsys.readouterr().err and not inside.exists()


def test_without_a_mesh_every_curve_the_view_frames_is_drawn(abc_emap_scene_dir, tmp_path, capsys):
    """EMAP's 00004926 has no mesh: visibility is framing; the curve left out is still named."""
    from edgedog.curve_files import EdgeCurves, write_edges
    from edgedog.groundtruth import abc_curves, ground_truth_for

    curves = abc_curves(ground_truth_for(abc_emap_scene_dir))
    pred = tmp_path / "pred.obj"
    write_edges(pred, EdgeCurves(polylines=[c.polyline for c in curves[1:]]))
    figure = tmp_path / "emap.png"
    assert main(["eval", str(pred), "--scene", str(abc_emap_scene_dir), "--frame", "gt", "--per-curve",
                 "--json", str(tmp_path / "e.json"), "--figure", str(figure), "--figure-views", "1"]) == 0
    assert "figure written to" in capsys.readouterr().out
    report = json.loads((tmp_path / "e.json").read_text())["per_curve"]
    missed = [c["id"] for c in report["curves"] if c["missed"]]
    assert missed == [curves[0].id]
    assert imread(figure).shape[:2] == (600, 500) and _missed_colour_near(imread(figure)).sum() > 20
