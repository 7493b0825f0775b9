"""`edgedog make-scene --cad FILE`: a STEP or BREP file as a scene with the same exact ground
truth as the solid it was written from, and bad CAD files refused in one line, nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import build123d as bd
import numpy as np
import pytest
from scipy.spatial import cKDTree

from edgedog.cli import main
from edgedog.groundtruth import ground_truth_for
from edgedog.scenes import load_scene
from edgedog.synthetic import cad_file
from edgedog.synthetic.shapes import make_part
from tests.helpers.bad_inputs import Case, assert_fails_cleanly, cases_as_params, snapshot

VIEWS, SIZE = 4, 96
BOX = bd.Box(30.0, 20.0, 10.0)  # millimetres


def make_scene(source: Path, out: Path, *options) -> int:
    return main(["make-scene", "--cad", str(source), "--out", str(out), "--views", str(VIEWS), "--size",
                 str(SIZE), "--detector", "canny", *options])


@pytest.mark.parametrize("suffix, options", [(".step", []), (".brep", ["--unit", "mm"])])
def test_a_part_written_to_a_cad_file_keeps_its_ground_truth(tmp_path, suffix, options):
    part = make_part("plate-holes", 1)  # lines and circles, holes through a plate
    source = tmp_path / f"plate{suffix}"
    (bd.export_step if suffix == ".step" else bd.export_brep)(part.solid, str(source))
    assert make_scene(source, tmp_path / "scene", *options) == 0
    scene = load_scene(tmp_path / "scene")
    assert len(scene) == VIEWS and scene.detectors == ["canny"]
    points, expected = ground_truth_for(scene.root).load(), part.ground_truth()
    # The same points, curve by curve, though the file may list the edges in another order and
    # direction: each point within a micrometre of one of the other set's, both ways.
    assert points.shape == expected.shape
    for a, b in ((points, expected), (expected, points)):
        assert cKDTree(b).query(a)[0].max() < 1e-6
    manifest = json.loads((tmp_path / "scene" / "edgedog_scene.json").read_text())
    assert manifest["shape"] == source.name and manifest["dimensions"]["width"] == 1.0
    assert manifest["dimensions"]["unit_mm"] == pytest.approx(1.0)  # the part was 1 unit = 1 mm long


def test_the_file_is_normalised_like_an_abc_object_in_its_own_unit(tmp_path):
    bd.export_step(BOX, str(tmp_path / "box.step"), unit=bd.Unit.CM)
    assert make_scene(tmp_path / "box.step", tmp_path / "scene") == 0
    points = ground_truth_for(tmp_path / "scene").load()
    np.testing.assert_allclose([points.min(0), points.max(0)], [[0, 1 / 6, 1 / 3], [1, 5 / 6, 2 / 3]],
                               atol=1e-9)
    dimensions = json.loads((tmp_path / "scene" / "edgedog_scene.json").read_text())["dimensions"]
    assert dimensions["unit_mm"] == pytest.approx(300.0)  # 30 cm long
    assert [dimensions[k] for k in ("width", "depth", "height")] == pytest.approx([1, 2 / 3, 1 / 3])


def step_without_unit(folder: Path) -> Path:
    """A box's STEP file whose representation context lists no length unit."""
    path = folder / "unitless.step"
    bd.export_step(BOX, str(path))
    text = path.read_text()
    length_unit = next(line.split("=")[0].strip() for line in text.splitlines() if "LENGTH_UNIT()" in line)
    units = f"(({length_unit},"
    assert text.count(units) == 1
    path.write_text(text.replace(units, "(("))
    return path


def test_a_unit_less_step_file_takes_the_unit_it_is_given(tmp_path):
    assert make_scene(step_without_unit(tmp_path), tmp_path / "scene", "--unit", "cm") == 0
    dimensions = json.loads((tmp_path / "scene" / "edgedog_scene.json").read_text())["dimensions"]
    assert dimensions["unit_mm"] == pytest.approx(300.0)  # 30 units of 1 cm


def cad_case(name: str, write, *words, options=()) -> Case:
    """`make-scene --cad` on the file `write(folder)` makes; the error names it and `words`."""
    def build(folder: Path):
        source = write(folder)
        argv = ["make-scene", "--cad", source, "--out", folder / "scene", "--views", "2", "--size", "32",
                "--detector", "canny", *options]
        return argv, [str(source), *words]
    return Case(name, build)


def written(name: str, content: str | bytes):
    def write(folder: Path) -> Path:
        path = folder / name
        (path.write_bytes if isinstance(content, bytes) else path.write_text)(content)
        return path
    return write


def exported(name: str, shape):
    def write(folder: Path) -> Path:
        path = folder / name
        if path.suffix == ".step":
            bd.export_step(shape, str(path))
        else:
            bd.export_brep(shape, str(path))
        return path
    return write


CUBE = bd.Box(1, 1, 1, align=(bd.Align.MIN,) * 3)
CASES = [
    cad_case("empty", written("empty.step", ""), "empty file"),
    cad_case("not-step", written("notes.step", "ISO-10303-21 maybe\n"), "not a readable STEP file"),
    cad_case("not-brep", written("part.brep", b"\x00\x01 binary"), "not a readable BREP file",
             options=("--unit", "mm")),
    cad_case("other-suffix", written("part.stl", "solid x\nendsolid x\n"), "STEP", "BREP"),
    cad_case("missing", lambda folder: folder / "absent.step", "file not found"),
    cad_case("a-face-only", exported("face.step", CUBE.faces()[0]), "no solid", "1 face"),
    cad_case("an-open-shell", exported("shell.step", bd.Shell(CUBE.faces()[:5])), "no solid"),
    cad_case("non-manifold", exported("touching.brep", CUBE + bd.Pos(1, 1, 0) * CUBE), "not manifold",
             options=("--unit", "mm")),
    cad_case("unit-less-step", step_without_unit, "no length unit", "--unit"),
    cad_case("unit-less-brep", exported("part.brep", CUBE), "no unit", "--unit"),
    cad_case("unit-twice", exported("part.step", CUBE), "declares its length unit", options=("--unit", "cm")),
    cad_case("huge", exported("bridge.step", bd.Box(200_000, 10_000, 5_000)), "200 m", "100 m"),
    cad_case("no-sharp-edge", exported("ball.step", bd.Sphere(5)), "no sharp edges"),
]


def test_unit_is_for_cad_files_only(tmp_path, capsys):
    assert main(["make-scene", "--shape", "box", "--unit", "mm", "--out", str(tmp_path / "scene")]) == 2
    assert "--unit is the length unit of a --cad file" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("case", cases_as_params(CASES))
def test_a_bad_cad_file_is_one_line_and_nothing_is_written(case, tmp_path):
    assert_fails_cleanly(case, tmp_path)
    assert not (tmp_path / "scene").exists() and not list(tmp_path.glob(".*partial"))


def test_too_many_faces_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(cad_file, "MAX_FACES", 5)
    case = cad_case("many-faces", exported("box.step", CUBE), "6 faces", "more than 5")
    assert_fails_cleanly(case, tmp_path)
    assert sorted(snapshot(tmp_path)) == ["box.step"]
