"""`edgedog make-scene`: loadable scenes with their ground truth, and degradations that do what
they say (small images and few views: each scene takes well under a second)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from edgedog.cli import main
from edgedog.groundtruth import ground_truth_for
from edgedog.scenes import load_scene
from edgedog.scenes.nerf import load_nerf
from edgedog.synthetic.cameras import orbit_cameras
from edgedog.synthetic.degrade import DROPS_PER_VIEW
from edgedog.synthetic.shapes import make_part

SIZE, VIEWS = 128, 6


def make_scene(folder, *options, shape="plate-holes", seed=3) -> int:
    return main(["make-scene", "--shape", shape, "--out", str(folder), "--views", str(VIEWS),
                 "--size", str(SIZE), "--seed", str(seed), "--detector", "canny", *options])


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scenes") / "clean"
    assert make_scene(folder) == 0
    return folder


def read(path) -> np.ndarray:
    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


def frames(folder) -> list[dict]:
    return json.loads((folder / "transforms_train.json").read_text())["frames"]


def test_make_scene_writes_a_loadable_abc_nef_scene(clean, capsys):
    scene = load_scene(clean)
    assert scene.format == "nerf" and len(scene) == VIEWS and scene.detectors == ["canny"]
    part_points = make_part("plate-holes", 3).ground_truth()
    np.testing.assert_allclose(ground_truth_for(scene.root).load(), part_points)
    for i, expected in enumerate(orbit_cameras(VIEWS, SIZE)):  # the ABC-NEF orbit, f scaled with size
        np.testing.assert_allclose(scene.camera(i).w2c, expected.w2c, atol=1e-9)
        np.testing.assert_allclose(scene.camera(i).K, expected.K)
        assert np.isclose(scene.camera(i).K[0, 0], 1111.11 * SIZE / 800)
    assert len(load_nerf(clean, "val")) == 4
    rgba = read(clean / "train_img" / "0.png")
    assert rgba.shape == (SIZE, SIZE, 4) and rgba[0, 0, 3] == 0 and rgba[..., 3].max() == 255
    manifest = json.loads((clean / "edgedog_scene.json").read_text())
    assert manifest["shape"] == "plate-holes" and manifest["edge_detector"] == "canny"
    curves = json.loads((clean / "gt" / "clean_curves.json").read_text())["curves"]
    assert {c["type"] for c in curves} == {"line", "arc"}
    assert not list(clean.parent.glob(".*partial"))


def test_the_pseudo_edges_are_high_on_the_ground_truth(clean):
    scene = load_scene(clean)
    points = ground_truth_for(scene.root).load()
    for i in range(len(scene)):
        edges = scene.load_edge_map(i)
        pixels, inside = scene.camera(i).pixels(points)
        assert inside.all()
        # Hidden curves count too, so the ratio is lower than on visible ones alone.
        assert edges[pixels[:, 1], pixels[:, 0]].mean() > 5 * edges.mean()


def test_seeds_change_the_part_and_renamed_scenes_keep_their_ground_truth(clean, tmp_path):
    other = tmp_path / "other"
    assert make_scene(other, seed=4) == 0
    dims = [json.loads((f / "edgedog_scene.json").read_text())["dimensions"] for f in (clean, other)]
    assert dims[0] != dims[1]
    renamed = tmp_path / "renamed"
    other.rename(renamed)
    assert ground_truth_for(load_scene(renamed).root).sampled_ply.name == "other_0.005.ply"


def test_an_existing_folder_is_refused_in_one_line(clean, capsys):
    assert make_scene(clean) == 2
    stderr = capsys.readouterr().err
    assert stderr == f"edgedog: error: {clean}: already exists; choose another folder or remove it\n"


@pytest.mark.parametrize("options, message", [
    (["--drop-edges", "1.5"], "--drop-edges is a fraction"),
    (["--keep-views", "9"], "--keep-views must be between 1 and --views"),
    (["--pose-noise-mm", "-1"], "noise levels must not be negative"),
    (["--detector", "foo"], "unknown detector 'foo'"),
])
def test_bad_options_are_one_line_errors(tmp_path, capsys, options, message):
    assert make_scene(tmp_path / "scene", *options) == 2
    stderr = capsys.readouterr().err
    assert message in stderr and stderr.count("\n") == 1 and not list(tmp_path.iterdir())


def test_pose_noise_moves_the_written_poses_only(clean, tmp_path):
    noisy = tmp_path / "noisy"
    assert make_scene(noisy, "--pose-noise-deg", "2", "--pose-noise-mm", "5") == 0
    for frame, truth in zip(frames(noisy), frames(clean)):
        written, true = np.array(frame["transform_matrix"]), np.array(frame["true_transform_matrix"])
        np.testing.assert_allclose(true, truth["transform_matrix"])
        cos = (np.trace(written[:3, :3] @ true[:3, :3].T) - 1) / 2
        assert np.isclose(np.degrees(np.arccos(cos)), 2.0)
        assert np.isclose(np.linalg.norm(written[:3, 3] - true[:3, 3]), 0.005)
    # The images are rendered with the true poses.
    np.testing.assert_array_equal(read(noisy / "train_img" / "2.png"), read(clean / "train_img" / "2.png"))


def test_image_noise_has_the_asked_std_on_the_object(clean, tmp_path):
    noisy = tmp_path / "noisy"
    assert make_scene(noisy, "--image-noise", "0.05") == 0
    image, reference = read(noisy / "train_img" / "1.png"), read(clean / "train_img" / "1.png")
    np.testing.assert_array_equal(image[..., 3], reference[..., 3])
    inside = reference[..., 3] > 0
    difference = image[..., :3].astype(float) - reference[..., :3]
    assert difference[inside].std() == pytest.approx(0.05 * 255, rel=0.1)
    assert np.all(difference[~inside] == 0)
    assert frames(noisy) == frames(clean)


def test_dropped_edges_spoil_the_asked_share_of_views(clean, tmp_path):
    spoiled = tmp_path / "spoiled"
    assert make_scene(spoiled, "--drop-edges", "0.5") == 0
    changed = []
    for i in range(VIEWS):
        edges, reference = read(spoiled / "train" / f"{i}.png"), read(clean / "train" / f"{i}.png")
        assert np.all(edges <= reference)  # only removed, never added
        lost = (reference > 127) & (edges == 0)
        if lost.any():
            changed.append(i)
            # DROPS_PER_VIEW round patches, each 1/16 of the width in radius.
            count = cv2.connectedComponents(cv2.dilate(lost.astype(np.uint8), np.ones((9, 9))))[0] - 1
            assert 1 <= count <= DROPS_PER_VIEW
    assert len(changed) == VIEWS // 2


def test_keep_views_writes_a_random_subset_of_the_orbit(clean, tmp_path):
    fewer = tmp_path / "fewer"
    assert make_scene(fewer, "--keep-views", "3") == 0
    names = [f["file_path"] for f in frames(fewer)]
    everything = {f["file_path"]: f["transform_matrix"] for f in frames(clean)}
    assert len(names) == 3 and set(names) < set(everything)
    for frame in frames(fewer):
        assert frame["transform_matrix"] == everything[frame["file_path"]]
    assert len(load_scene(fewer)) == 3


def test_help_lists_the_shapes(capsys):
    with pytest.raises(SystemExit):
        main(["make-scene", "--help"])
    out = capsys.readouterr().out
    assert "usage: edgedog make-scene" in out and "l-bracket" in out and "--pose-noise-deg" in out
