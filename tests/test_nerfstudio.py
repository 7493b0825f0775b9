"""nerfstudio scenes (`transforms.json`): intrinsics given once or per frame, masks, the applied
transform, downscaled copies, and one line naming the file and frame for each bad input.
Distorted cameras: tests/test_distortion.py."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from edgedog.errors import InputError
from edgedog.scenes import load_scene
from tests.helpers.cli_runner import edgedog

W, H = 64, 48


def write_scene(root: Path, frames: int = 2, **meta) -> Path:
    """A pinhole nerfstudio scene: `frames` views of a white square, cameras 3 units from the
    origin looking at it, global intrinsics; `meta` entries added (None removes one)."""
    (root / "images").mkdir(parents=True)
    image = np.zeros((H, W, 3), np.uint8)
    image[16:32, 24:40] = 255
    listed = []
    for i in range(frames):
        cv2.imwrite(str(root / "images" / f"frame_{i:05d}.png"), image)
        c2w = np.eye(4)
        c2w[:3, 3] = [0.1 * i, 0.0, 3.0]  # OpenGL: looks down -Z, towards the origin
        listed.append({"file_path": f"images/frame_{i:05d}.png", "transform_matrix": c2w.tolist(),
                       "depth_file_path": f"depths/frame_{i:05d}.png"})  # absent: ignored
    content = {"camera_model": "PINHOLE", "fl_x": 50.0, "fl_y": 52.0, "cx": 32.0, "cy": 24.0, "w": W, "h": H,
               "frames": listed, **meta}
    (root / "transforms.json").write_text(json.dumps({k: v for k, v in content.items() if v is not None}))
    return root


def edit(root: Path, change) -> Path:
    """Apply `change` to the parsed transforms.json and write it back; returns that file."""
    path = root / "transforms.json"
    meta = json.loads(path.read_text())
    change(meta)
    path.write_text(json.dumps(meta))
    return path


def test_a_pinhole_scene_loads_and_info_names_its_format(tmp_path):
    root = write_scene(tmp_path / "scene")
    scene = load_scene(root)
    assert scene.format == "nerfstudio" and [v.name for v in scene.views] == ["frame_00000", "frame_00001"]
    camera = scene.camera(1)
    # nerfstudio's cx, cy count from the top-left pixel's corner; edgedog's from its centre.
    np.testing.assert_allclose(camera.K, [[50, 0, 31.5], [0, 52, 23.5], [0, 0, 1]])
    np.testing.assert_allclose(camera.center, [0.1, 0.0, 3.0])
    np.testing.assert_allclose(camera.forward, [0.0, 0.0, -1.0])
    assert all(view.distortion is None and view.mask_path is None for view in scene.views)
    assert scene.views[0].image_path == root / "images" / "frame_00000.png"  # pinholes: read in place
    info = edgedog("info", root)
    assert info.returncode == 0, info.stderr
    assert "format        nerfstudio" in info.stdout and "2 at 64x48" in info.stdout


def test_frame_intrinsics_override_the_global_ones(tmp_path):
    root = write_scene(tmp_path / "scene", fl_y=None)
    edit(root, lambda m: (m["frames"][1].update(fl_x=60.0, fl_y=61.0, cx=30.0), m.update(fl_y=50.0)))
    scene = load_scene(root)
    np.testing.assert_allclose(scene.camera(0).K[0], [50, 0, 31.5])
    np.testing.assert_allclose(scene.camera(1).K[:2], [[60, 0, 29.5], [0, 61, 23.5]])


def test_masks_and_the_applied_transform(tmp_path):
    root = write_scene(tmp_path / "scene", frames=1)
    (root / "masks").mkdir()
    cv2.imwrite(str(root / "masks" / "frame_00000.png"), np.full((H, W), 255, np.uint8))
    applied = [[0.0, 1.0, 0.0, 0.5], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 2.0]]  # ns-process-data's
    edit(root, lambda m: (m["frames"][0].update(mask_path="masks/frame_00000.png"),
                          m.update(applied_transform=applied)))
    scene = load_scene(root)
    assert scene.views[0].mask_path == root / "masks" / "frame_00000.png"
    assert scene.load_mask(0).all()
    # world_to_gt undoes the applied transform: a capture-frame point comes back to itself.
    point = np.array([0.3, -0.2, 0.7, 1.0])
    transformed = np.vstack([applied, [0, 0, 0, 1]]) @ point
    np.testing.assert_allclose(scene.world_to_gt @ transformed, point, atol=1e-12)


def test_downscaled_copies_stand_in_for_missing_full_resolution_images(tmp_path):
    root = write_scene(tmp_path / "scene", frames=1)
    (root / "images").rename(root / "images_2")
    small = cv2.resize(cv2.imread(str(root / "images_2" / "frame_00000.png")), (W // 2, H // 2))
    cv2.imwrite(str(root / "images_2" / "frame_00000.png"), small)
    scene = load_scene(root)
    view = scene.views[0]
    assert view.image_path == root / "images_2" / "frame_00000.png"
    assert (view.camera.width, view.camera.height) == (W // 2, H // 2)
    # Scaled about the image's corner: f / 2, and nerfstudio's cx 32 becomes 16, 15.5 in edgedog's terms.
    np.testing.assert_allclose(view.camera.K[:2], [[25, 0, 15.5], [0, 26, 11.5]])


@pytest.mark.parametrize("change, frame, words", [
    (lambda m: m.update(camera_model="EQUIRECTANGULAR"), 0, ("unknown camera_model 'EQUIRECTANGULAR'",)),
    (lambda m: m["frames"][1].update(camera_model="FISHEYE624"), 1, ("FISHEYE624",)),
    (lambda m: m.pop("fl_y"), 0, ("no fl_y",)),
    (lambda m: (m.pop("w"), m.pop("h")), 0, ("no w, h",)),
    (lambda m: m["frames"][1].update(file_path="../outside.png"), 1, ("'../outside.png'", "outside")),
    (lambda m: m["frames"][0].update(file_path="/etc/hostname"), 0, ("outside",)),
    (lambda m: m["frames"][1].update(mask_path="../mask.png"), 1, ("mask_path", "outside")),
    (lambda m: m["frames"][1].update(file_path="images/nope.png"), 1, ("'images/nope.png' not found",)),
    (lambda m: m["frames"][1].update(k1=float("nan")), 1, ("k1", "nan")),
    (lambda m: m.update(camera_model="OPENCV", k2=float("inf")), None, ("k2", "inf")),  # every frame's
    (lambda m: m.update(camera_model="OPENCV", k4=0.01), 0, ("k4", "no OpenCV counterpart")),
    (lambda m: m.update(camera_model="OPENCV_FISHEYE", p1=0.01), 0, ("tangential",)),
    (lambda m: m["frames"][1].update(fl_x=float("nan")), 1, ("nan",)),
    (lambda m: m["frames"][0].pop("transform_matrix"), 0, ("no transform_matrix",)),
    (lambda m: m["frames"].append(3), 2, ("not an object",)),
    (lambda m: m.update(applied_transform=[[1, 0, 0, 0]]), None, ("applied_transform", "shape")),
    (lambda m: m.update(frames={}), None, ("no 'frames' list",)),
], ids=["unknown-model", "unknown-frame-model", "no-fl_y", "no-size", "outside", "absolute-outside",
        "mask-outside", "missing-image", "nan-k1", "inf-k2", "opencv-k4", "fisheye-p1", "nan-focal",
        "no-pose", "frame-not-an-object", "applied-1x4", "frames-not-a-list"])
def test_bad_input_is_one_line_naming_the_file_and_frame(tmp_path, change, frame, words):
    (tmp_path / "outside.png").write_bytes(b"")
    path = edit(write_scene(tmp_path / "scene"), change)
    with pytest.raises(InputError) as info:
        load_scene(path.parent)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path}: "), message
    # The loader says 'frame N'; the JSON reader, which refuses NaN and Inf first, 'frames[N]'.
    assert frame is None or f"frame {frame}:" in message or f"frames[{frame}]" in message, message
    for word in words:
        assert word.lower() in message.lower(), message


def test_bad_input_on_the_command_line_is_one_line(tmp_path):
    path = edit(write_scene(tmp_path / "scene"), lambda m: m.update(camera_model="SPHERICAL"))
    result = edgedog("info", path.parent)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and result.stderr.startswith(f"edgedog: error: {path}: frame 0: ")


def test_files_outside_the_folder_load_when_allowed(tmp_path, monkeypatch):
    root = write_scene(tmp_path / "scene")
    (root / "images" / "frame_00001.png").rename(tmp_path / "frame_00001.png")
    edit(root, lambda m: m["frames"][1].update(file_path="../frame_00001.png"))
    monkeypatch.setenv("EDGEDOG_ALLOW_OUTSIDE_FILES", "1")
    assert load_scene(root).views[1].image_path == tmp_path / "frame_00001.png"
