"""Bad scene input fails with one clear line: the offending file first, then the problem.

Every malformed scene is built by hand in pytest's tmp_path (a few 16x16 images), so these
tests need no shared data.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from edgedog.errors import ConfigError, EdgeDogError, InputError
from edgedog.scenes import detect_format, load_scene
from edgedog.scenes.images import parse_background
from tests.helpers.scene_builders import (
    ANGLE_X,
    SIZE,
    make_colmap,
    make_emap,
    make_nerf,
    make_neus,
    nerf_meta,
    write_json,
    write_png,
)

# --- helpers -----------------------------------------------------------------------------------


def assert_one_line(err: BaseException, path: Path, *words: str) -> str:
    """`err` is an InputError whose message is one line '<path>: <problem>' naming `words`."""
    assert isinstance(err, InputError)
    assert isinstance(err, EdgeDogError)
    message = str(err)
    assert "\n" not in message and "\r" not in message, message
    path = Path(path).resolve()
    assert Path(err.path).resolve() == path
    assert message.startswith(f"{path}: "), message
    for word in words:
        assert word.lower() in message.lower(), f"{word!r} not in {message!r}"
    return message


# --- the hand-made scenes are valid to begin with ---------------------------------------------


def test_valid_hand_made_scenes_load(tmp_path):
    nerf = load_scene(make_nerf(tmp_path / "nerf"))
    assert nerf.format == "nerf" and len(nerf) == 3
    for i in range(3):
        assert nerf.load_image(i).shape == (SIZE, SIZE, 3)
    emap = load_scene(make_emap(tmp_path / "emap"))
    assert emap.format == "emap" and emap.load_image(1).shape == (SIZE, SIZE, 3)
    neus = load_scene(make_neus(tmp_path / "neus"))
    assert neus.format == "neus" and neus.load_mask(1).shape == (SIZE, SIZE)


# --- the scene folder --------------------------------------------------------------------------


def test_missing_scene_folder(tmp_path):
    missing = tmp_path / "no_such_scene"
    with pytest.raises(InputError) as info:
        load_scene(missing)
    assert_one_line(info.value, missing, "not found")
    with pytest.raises(InputError) as info:
        detect_format(missing)
    assert_one_line(info.value, missing, "not found")


def test_a_file_is_not_a_scene_folder(tmp_path):
    file = tmp_path / "transforms_train.json"
    file.write_text("{}")
    with pytest.raises(InputError) as info:
        load_scene(file)
    assert_one_line(info.value, file, "not a scene folder")


def test_folder_without_marker_file(tmp_path):
    folder = tmp_path / "photos"
    write_png(folder / "a.png")
    with pytest.raises(InputError) as info:
        load_scene(folder)
    message = assert_one_line(info.value, folder, "not a scene folder")
    # It lists what it looked for.
    for marker in ("transforms_train.json", "meta_data.json", "cameras_sphere.npz", "COLMAP"):
        assert marker in message


# --- NeRF / Blender ----------------------------------------------------------------------------


def test_nerf_frame_file_not_found(tmp_path):
    root = make_nerf(tmp_path / "scene")
    (root / "train" / "r_1.png").unlink()
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, root / "transforms_train.json", "r_1", "not found")


def test_nerf_truncated_json(tmp_path):
    root = make_nerf(tmp_path / "scene")
    transforms = root / "transforms_train.json"
    text = transforms.read_text()
    transforms.write_text(text[: len(text) // 2])
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, transforms, "invalid JSON", "line")


def test_nerf_json_is_not_an_object(tmp_path):
    root = make_nerf(tmp_path / "scene")
    transforms = write_json(root / "transforms_train.json", [1, 2, 3])
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, transforms, "frames")


@pytest.mark.parametrize("meta", [{"camera_angle_x": ANGLE_X}, {"camera_angle_x": ANGLE_X, "frames": []}])
def test_nerf_json_without_frames(tmp_path, meta):
    root = make_nerf(tmp_path / "scene")
    transforms = write_json(root / "transforms_train.json", meta)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, transforms, "frames")


def test_nerf_frame_without_transform_matrix(tmp_path):
    root = make_nerf(tmp_path / "scene")
    meta = nerf_meta(root)
    del meta["frames"][2]["transform_matrix"]
    transforms = write_json(root / "transforms_train.json", meta)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, transforms, "frame 2", "transform_matrix")


def test_nerf_without_focal(tmp_path):
    root = make_nerf(tmp_path / "scene")
    meta = nerf_meta(root)
    del meta["camera_angle_x"]
    transforms = write_json(root / "transforms_train.json", meta)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, transforms, "frame 0", "camera_angle_x")


def test_nerf_nan_in_transform_matrix(tmp_path):
    root = make_nerf(tmp_path / "scene")
    meta = nerf_meta(root)
    meta["frames"][1]["transform_matrix"][0][3] = float("nan")
    transforms = write_json(root / "transforms_train.json", meta)
    assert "NaN" in transforms.read_text()
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, transforms, "frames[1]", "NaN")


def test_nerf_transform_matrix_of_wrong_shape(tmp_path):
    root = make_nerf(tmp_path / "scene")
    meta = nerf_meta(root)
    meta["frames"][0]["transform_matrix"] = meta["frames"][0]["transform_matrix"][:3]
    transforms = write_json(root / "transforms_train.json", meta)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, transforms, "frame 0", "shape")


def test_nerf_transform_matrix_not_numeric(tmp_path):
    root = make_nerf(tmp_path / "scene")
    meta = nerf_meta(root)
    meta["frames"][0]["transform_matrix"][1][1] = "one"
    transforms = write_json(root / "transforms_train.json", meta)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, transforms, "frame 0", "numeric")


@pytest.mark.parametrize("kind", ["scaled", "reflected", "sheared"])
def test_nerf_non_rotation_matrix(tmp_path, kind):
    root = make_nerf(tmp_path / "scene")
    meta = nerf_meta(root)
    c2w = np.array(meta["frames"][1]["transform_matrix"])
    if kind == "scaled":
        c2w[:3, :3] *= 2.0
    elif kind == "reflected":
        c2w[:3, 0] *= -1.0
    else:
        c2w[0, 1] += 0.3
    meta["frames"][1]["transform_matrix"] = c2w.tolist()
    transforms = write_json(root / "transforms_train.json", meta)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, transforms, "frame 1", "rotation")


def test_nerf_image_of_wrong_size(tmp_path):
    """Sizes are read from the headers when the scene loads: the odd image is named."""
    root = make_nerf(tmp_path / "scene")
    odd = write_png(root / "train" / "r_1.png", width=20, height=SIZE)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, odd, f"20x{SIZE}", f"{SIZE}x{SIZE}")


@pytest.mark.parametrize("odd", [0, 2])
def test_a_wrong_sized_image_is_named_even_when_it_comes_first(tmp_path, odd):
    """ABC-NEF layout: the scene's size is most images' size, so a wrong-sized first image is
    blamed, not the correct edge map it used to set the size for."""
    root = make_nerf(tmp_path / "scene")
    for i in range(3):
        write_png(root / "train_img" / f"r_{i}.png", width=20 if i == odd else SIZE)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, root / "train_img" / f"r_{odd}.png", f"20x{SIZE}", f"{SIZE}x{SIZE}")


def test_nerf_undecodable_image(tmp_path):
    """A damaged image is listed when the scene loads and fails, named, when it is read."""
    root = make_nerf(tmp_path / "scene")
    broken = root / "train" / "r_2.png"
    broken.write_bytes(b"\x89PNG\r\n\x1a\n this is not really a png" * 4)
    scene = load_scene(root)
    assert list(scene.damaged) == [broken] and "PNG" in scene.damaged[broken]
    with pytest.raises(InputError) as info:
        scene.load_image(2)
    assert_one_line(info.value, broken, "decoded")


def test_an_undecodable_first_image_does_not_set_the_scene_size(tmp_path):
    root = make_nerf(tmp_path / "scene")
    broken = root / "train" / "r_0.png"
    broken.write_bytes(b"garbage" * 10)
    scene = load_scene(root)
    assert scene.camera(1).width == SIZE and list(scene.damaged) == [broken]
    with pytest.raises(InputError) as info:
        scene.load_image(0)
    assert_one_line(info.value, broken, "decoded")


def test_a_scene_without_any_readable_image(tmp_path):
    root = make_nerf(tmp_path / "scene")
    for i in range(3):
        (root / "train" / f"r_{i}.png").write_bytes(b"garbage")
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, root / "transforms_train.json", "none of its 3 images")


def test_nerf_image_deleted_after_load(tmp_path):
    root = make_nerf(tmp_path / "scene")
    scene = load_scene(root)
    gone = scene.views[1].image_path
    gone.unlink()
    with pytest.raises(InputError) as info:
        scene.load_image(1)
    assert_one_line(info.value, gone, "not found")


def test_nef_image_folder_without_the_image(tmp_path):
    """ABC-NEF layout: train/ holds edge maps, train_img/ the images; one image is missing."""
    root = make_nerf(tmp_path / "scene")
    for i in (0, 1):  # no train_img/r_2.png
        write_png(root / "train_img" / f"r_{i}.png")
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, root / "train_img", "r_2", "frame 2")


def test_edge_map_errors(tmp_path):
    root = make_nerf(tmp_path / "scene")
    scene = load_scene(root)
    with pytest.raises(InputError) as info:
        scene.load_edge_map(0)
    assert_one_line(info.value, root, "no edge maps")
    for i in range(3):
        write_png(root / "edge_PiDiNet" / f"r_{i}.png", channels=1)
    scene = load_scene(root)
    with pytest.raises(InputError) as info:
        scene.load_edge_map(0, "dexined")
    assert_one_line(info.value, root, "dexined", "pidinet")
    odd = write_png(root / "edge_PiDiNet" / "r_2.png", width=SIZE, height=8, channels=1)
    with pytest.raises(InputError) as info:
        scene.load_edge_map(2)
    assert_one_line(info.value, odd, f"{SIZE}x8", f"{SIZE}x{SIZE}")
    odd.write_bytes(b"not an image")
    with pytest.raises(InputError) as info:
        scene.load_edge_map(2, "pidinet")
    assert_one_line(info.value, odd, "decoded")


# --- EMAP --------------------------------------------------------------------------------------


def test_emap_nan_camtoworld(tmp_path):
    root = make_emap(tmp_path / "scene")
    meta_path = root / "meta_data.json"
    meta = json.loads(meta_path.read_text())
    meta["frames"][1]["camtoworld"][2][2] = float("nan")
    write_json(meta_path, meta)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, meta_path, "frames[1]", "NaN")


def test_emap_missing_intrinsics(tmp_path):
    root = make_emap(tmp_path / "scene")
    meta_path = root / "meta_data.json"
    meta = json.loads(meta_path.read_text())
    del meta["frames"][0]["intrinsics"]
    write_json(meta_path, meta)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, meta_path, "frame 0", "intrinsics")


@pytest.mark.parametrize(
    "edit, words",
    [
        (lambda m: m.pop("width"), ("width",)),
        (lambda m: m.update(frames=[]), ("frames",)),
        (lambda m: m.update(camera_model="OPENCV_FISHEYE"), ("camera_model", "OPENCV_FISHEYE")),
        (lambda m: m["frames"][0]["intrinsics"][0].__setitem__(0, -5.0), ("frame 0", "focal")),
        (lambda m: m["frames"][1].__setitem__("intrinsics", [[1, 0], [0, 1]]), ("frame 1", "shape")),
        (lambda m: m.update(worldtogt=[[float("nan")] * 4] * 4), ("worldtogt", "NaN")),
    ],
    ids=["no-width", "no-frames", "fisheye", "negative-focal", "intrinsics-2x2", "nan-worldtogt"],
)
def test_emap_other_malformed_metadata(tmp_path, edit, words):
    root = make_emap(tmp_path / "scene")
    meta_path = root / "meta_data.json"
    meta = json.loads(meta_path.read_text())
    edit(meta)
    write_json(meta_path, meta)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, meta_path, *words)


def test_emap_truncated_json(tmp_path):
    root = make_emap(tmp_path / "scene")
    meta_path = root / "meta_data.json"
    text = meta_path.read_text()
    meta_path.write_text(text[: len(text) // 3])
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, meta_path, "invalid JSON")


# --- NeuS / DTU --------------------------------------------------------------------------------


@pytest.mark.parametrize("corruption", ["garbage", "truncated"])
def test_neus_corrupt_cameras(tmp_path, corruption):
    root = make_neus(tmp_path / "scene")
    cameras = root / "cameras_sphere.npz"
    data = cameras.read_bytes()
    broken = b"garbage, not an archive\n" * 5 if corruption == "garbage" else data[: len(data) // 2]
    cameras.write_bytes(broken)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, cameras, ".npz")


def test_neus_missing_world_mat(tmp_path):
    root = make_neus(tmp_path / "scene", frames=3, skip_key="world_mat_2")
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, root / "cameras_sphere.npz", "world_mat_2", "002.png")


def test_neus_nan_world_mat(tmp_path):
    root = make_neus(tmp_path / "scene")
    cameras = root / "cameras_sphere.npz"
    arrays = dict(np.load(cameras))
    arrays["world_mat_1"][0, 0] = np.nan
    np.savez(cameras, **arrays)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, cameras, "world_mat_1", "NaN")


def test_neus_no_images(tmp_path):
    root = make_neus(tmp_path / "scene")
    for image in (root / "image").iterdir():
        image.unlink()
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, root / "image", "no images")


def test_neus_mask_count_mismatch(tmp_path):
    root = make_neus(tmp_path / "scene")
    (root / "mask" / "001.png").unlink()
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, root / "mask", "1 masks for 2 images")


# --- COLMAP ------------------------------------------------------------------------------------


def test_colmap_hand_made_model_loads(tmp_path):
    scene = load_scene(make_colmap(tmp_path / "scene"))
    assert scene.format == "colmap" and len(scene) == 1


def test_colmap_camera_model_opencv_cannot_undistort(tmp_path):
    # OPENCV and the other models OpenCV undistorts load: tests/test_distortion.py.
    params = [20.0, 20.0, 8.0, 8.0, 0.01]  # fx fy cx cy omega
    root = make_colmap(tmp_path / "scene", model="FOV", params=params)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, root / "sparse" / "0", "FOV", "undistort")


def test_colmap_nan_distortion(tmp_path):
    params = [20.0, 20.0, 8.0, 8.0, float("nan"), 0.01, 0.0, 0.0]  # fx fy cx cy k1 k2 p1 p2
    root = make_colmap(tmp_path / "scene", model="OPENCV", params=params)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, root / "sparse" / "0", "unreadable COLMAP model")  # pycolmap checks


@pytest.mark.parametrize(
    "content",
    ["garbage\n", "1 NO_SUCH_MODEL 16 16 20 8 8\n", "1 PINHOLE 16 16 20\n"],
    ids=["garbage", "unknown-model", "too-few-params"],
)
def test_colmap_unreadable_cameras_txt(tmp_path, content):
    root = make_colmap(tmp_path / "scene")
    model = root / "sparse" / "0"
    (model / "cameras.txt").write_text(content)
    with pytest.raises(InputError) as info:
        load_scene(root)
    assert_one_line(info.value, model, "COLMAP")


# --- options -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, expected",
    [
        ("black", (0.0, 0.0, 0.0)),
        ("white", (1.0, 1.0, 1.0)),
        ("none", None),
        ("0.5,0.25,1", (0.5, 0.25, 1.0)),
        ("0, 1, 0", (0.0, 1.0, 0.0)),
        ("1,1,1", (1.0, 1.0, 1.0)),
    ],
)
def test_parse_background_good(text, expected):
    assert parse_background(text) == expected


@pytest.mark.parametrize(
    "text", ["", "red", "1,2,3", "0.5,0.5", "0.1,0.2,0.3,0.4", "a,b,c", "-0.1,0,0", "nan,0,0", "0.5,,0.5"]
)
def test_parse_background_bad(text):
    with pytest.raises(ValueError) as info:
        parse_background(text)
    message = str(info.value)
    assert "\n" not in message
    assert "background" in message and repr(text) in message


@pytest.mark.parametrize("downscale", [0, 1.5, -2, float("inf")])
def test_load_scene_rejects_bad_downscale(tmp_path, downscale):
    root = make_nerf(tmp_path / "scene")
    with pytest.raises(ConfigError, match=f"^downscale {downscale}: must be a positive integer$"):
        load_scene(root, downscale=downscale)


def test_load_scene_rejects_bad_downscale_before_touching_the_folder(tmp_path):
    with pytest.raises(ConfigError, match="--downscale 0"):
        load_scene(tmp_path / "missing", downscale=0, setting="--downscale")


def test_load_scene_rejects_a_downscale_that_leaves_no_pixels(tmp_path):
    root = make_nerf(tmp_path / "scene")
    assert load_scene(root, downscale=2).camera(0).width == SIZE // 2
    with pytest.raises(ConfigError, match="^--downscale 3: .* 5 pixels across .* use at most 2$"):
        load_scene(root, downscale=3, setting="--downscale")


# --- values of the wrong type in the metadata are InputErrors naming the file ------------------


def _edit_nerf(edit):
    def build(root):
        make_nerf(root)
        meta = nerf_meta(root)
        edit(meta)
        write_json(root / "transforms_train.json", meta)
        return root / "transforms_train.json"
    return build


def _edit_emap(edit):
    def build(root):
        make_emap(root)
        meta = json.loads((root / "meta_data.json").read_text())
        edit(meta)
        write_json(root / "meta_data.json", meta)
        return root / "meta_data.json"
    return build


def _neus_3x3_world_mat(root):
    make_neus(root)
    cameras = root / "cameras_sphere.npz"
    arrays = dict(np.load(cameras))
    arrays["world_mat_1"] = np.eye(3)
    np.savez(cameras, **arrays)
    return cameras


@pytest.mark.parametrize(
    "build",
    [
        pytest.param(_edit_nerf(lambda m: m.update(frames=[1, 2])), id="nerf-frame-not-object"),
        pytest.param(_edit_nerf(lambda m: m.update(camera_angle_x="wide")), id="nerf-angle-text"),
        pytest.param(_edit_nerf(lambda m: m.update(camera_angle_x=0)), id="nerf-angle-zero"),
        pytest.param(_edit_nerf(lambda m: m["frames"][0].update(file_path=5)), id="nerf-file-path-int"),
        pytest.param(_edit_nerf(lambda m: m.update(w="x", h=SIZE)), id="nerf-w-text"),
        pytest.param(_edit_emap(lambda m: m.update(frames=[1])), id="emap-frame-not-object"),
        pytest.param(_edit_emap(lambda m: m.update(width="wide")), id="emap-width-text"),
        pytest.param(_edit_emap(lambda m: m.update(scene_box=[1])), id="emap-scene-box-list"),
        pytest.param(_neus_3x3_world_mat, id="neus-world-mat-3x3"),
    ],
)
def test_wrongly_typed_values_are_input_errors(tmp_path, build):
    offending = build(tmp_path / "scene")
    with pytest.raises(InputError) as info:
        load_scene(tmp_path / "scene")
    assert_one_line(info.value, offending)
