"""Bad scene data and data files: each fails with one line naming the file or the option, exit 2,
no traceback, nothing that was there changed (the harness: tests/helpers/bad_inputs.py). Then direct
tests of the results that used to be silently wrong (stale edge maps, a truncated image decoded
in part, a mixed grey/RGBA scene said to have no masks).

The scenes are hand-made 16x16 ones (tests/helpers/scene_builders.py): each case costs one subprocess.
"""

from __future__ import annotations

import json
import os
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from plyfile import PlyData, PlyElement

from edgedog.commands.info import summary
from edgedog.edges.cache import ensure_edge_maps
from edgedog.edges.classical import SobelDetector
from edgedog.errors import InputError
from edgedog.scenes import ALLOW_OUTSIDE, load_scene
from edgedog.scenes.images import image_info, read_raw
from tests.helpers.bad_inputs import Case, assert_fails_cleanly, cases_as_params, edgedog
from tests.helpers.scene_builders import (
    SIZE,
    make_colmap,
    make_emap,
    make_nerf,
    make_neus,
    nerf_meta,
    write_json,
    write_png,
)

# --- building the cases ------------------------------------------------------------------------


def nerf(folder: Path, edit=None, frames: int = 3) -> Path:
    """A NeRF scene `folder/scene`, its transforms_train.json changed by `edit(meta)`."""
    root = make_nerf(folder / "scene", frames)
    if edit is not None:
        meta = nerf_meta(root)
        edit(meta)
        write_json(root / "transforms_train.json", meta)
    return root


def nef(folder: Path) -> Path:
    """The ABC-NEF layout: train/ holds the edge maps, train_img/ the images."""
    root = nerf(folder)
    for i in range(3):
        write_png(root / "train_img" / f"r_{i}.png")
    return root


def emap(folder: Path, edit) -> Path:
    root = make_emap(folder / "scene")
    meta = json.loads((root / "meta_data.json").read_text())
    edit(meta)
    write_json(root / "meta_data.json", meta)
    return root


def info_fails(make, *words):
    """A case: `edgedog info` on the scene `make(folder)` builds; the error names `words` (the
    scene's transforms_train.json first, unless `words` name other files)."""
    def build(folder: Path):
        root = make(folder)
        return ["info", root], [root / "transforms_train.json" if w is TRANSFORMS else w for w in words]
    return build


TRANSFORMS = object()  # stands for the scene's transforms_train.json in `info_fails`


def edited(edit):
    return lambda folder: nerf(folder, edit)


def nerf_edit(edit, *words):
    return info_fails(edited(edit), TRANSFORMS, *words)


def frame_value(index: int, key: str, value):
    return lambda meta: meta["frames"][index].__setitem__(key, value)


INF = float("inf")  # written to JSON as Infinity, which Python's json reads back


def updated(**values):
    return lambda meta: meta.update(values)


def intrinsics(frame: int, K):
    return frame_value(frame, "camera_intrinsics", K)


def pose_row(frame: int, row: int, values):
    return lambda meta: meta["frames"][frame]["transform_matrix"].__setitem__(row, values)


def emap_edit(edit, *words):
    """A case: `edgedog info` on an EMAP scene whose meta_data.json is changed by `edit`."""
    def build(folder: Path):
        root = emap(folder, edit)
        return ["info", root], [root / "meta_data.json", *words]
    return build


def matrix_entry(frame: int, row: int, column, value):
    def edit(meta):
        meta["frames"][frame]["transform_matrix"][row][column] = value
    return edit


def scene_symlink_loop(folder: Path):
    os.symlink("loop", folder / "loop")
    return ["info", "loop"], ["loop", "symlink loop"]


def loop_as_image_folder(folder: Path) -> Path:
    root = nerf(folder)
    os.symlink("train_img", root / "train_img")
    return root


def broken_image_folder(folder: Path) -> Path:
    root = nerf(folder)
    os.symlink(folder / "gone", root / "train_img")
    return root


def wrong_sized_first_image(folder: Path) -> Path:
    root = nef(folder)
    write_png(root / "train_img" / "r_0.png", width=20)
    return root


def outside_file_path(folder: Path) -> Path:
    write_png(folder / "elsewhere" / "x.png")
    return nerf(folder, frame_value(0, "file_path", "../elsewhere/x"))


def image_linked_outside(folder: Path) -> Path:
    root = nerf(folder)
    write_png(folder / "elsewhere.png")
    (root / "train" / "r_1.png").unlink()
    os.symlink(folder / "elsewhere.png", root / "train" / "r_1.png")
    return root


def edge_folder_linked_outside(folder: Path) -> Path:
    root = nerf(folder)
    for i in range(3):
        write_png(folder / "maps" / f"r_{i}.png", channels=1)
    os.symlink(folder / "maps", root / "edge_Canny")
    return root


def neus_image_linked_outside(folder: Path) -> Path:
    root = make_neus(folder / "scene")
    write_png(folder / "elsewhere.png")
    (root / "image" / "000.png").unlink()
    os.symlink(folder / "elsewhere.png", root / "image" / "000.png")
    return root


def neus_cameras(arrays) -> object:
    """A case: a NeuS scene whose cameras_sphere.npz holds `arrays(original)` instead."""
    def build(folder: Path):
        root = make_neus(folder / "scene")
        cameras = root / "cameras_sphere.npz"
        original = dict(np.load(cameras))
        np.savez_compressed(cameras, **arrays(original))
        return ["info", root], [cameras]
    return build


def with_object_array(arrays: dict) -> dict:
    arrays["world_mat_0"] = np.array([{"not": "a matrix"}], dtype=object)
    return arrays


def with_huge_array(arrays: dict) -> dict:
    arrays["world_mat_1"] = np.zeros(1 << 18)  # 2 MiB of zeros: a few KiB compressed
    return arrays


def colmap_with_unknown_camera(folder: Path):
    root = make_colmap(folder / "scene")
    model = root / "sparse" / "0"
    frames = model / "frames.txt"
    frames.write_text(frames.read_text().replace("CAMERA 1 1", "CAMERA 1 4294967295"))
    return ["info", root], [model, "unreadable COLMAP model"]


def emap_image_missing(folder: Path):
    root = make_emap(folder / "scene")
    (root / "color" / "1_colors.png").unlink()
    return ["info", root], [root / "color" / "1_colors.png", "not found"]


def truncated(path: Path, keep: float = 0.6) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


def random_image(path: Path, size: int = 64) -> Path:
    """A noisy image (so that its compressed data fills most of the file)."""
    rng = np.random.default_rng(zlib.crc32(path.name.encode()))
    assert cv2.imwrite(str(path), rng.integers(0, 256, (size, size, 3), dtype=np.uint8))
    return path


def edges_with_damaged_image(damage):
    """A case: `edgedog edges` (which reads every image) on a scene whose train/r_1 image is
    replaced by `damage(train folder)`, which returns the damaged file; nothing may be written."""
    def build(folder: Path):
        root = nerf(folder, lambda meta: meta.update(w=64, h=64))
        for i in range(3):
            random_image(root / "train" / f"r_{i}.png")
        (root / "train" / "r_1.png").unlink()
        damaged = damage(root / "train")
        return ["edges", root, "--detector", "sobel"], [damaged]
    return build


def truncated_png(train: Path) -> Path:
    path = random_image(train / "r_1.png")
    truncated(path)
    return path


def truncated_jpeg(train: Path) -> Path:
    path = random_image(train / "r_1.jpg")
    truncated(path)
    return path


def png_declaring_a_huge_size(train: Path) -> Path:
    path = random_image(train / "r_1.png")
    data = bytearray(path.read_bytes())
    data[16:24] = struct.pack(">II", 30000, 30000)  # IHDR width and height
    path.write_bytes(bytes(data))
    return path


def with_options(*options, frames: int = 3, command: str = "info"):
    return lambda folder: ([command, nerf(folder, frames=frames), *options], [options[0]])


def make_scene(*options):
    return lambda folder: (["make-scene", "--shape", "box", "--out", folder / "made", "--detector", "canny",
                            *options], [" ".join(options[:2])])


def evaluated(obj_text: str, *words):
    """A case: `edgedog eval pred.obj --gt gt.ply` with the prediction `obj_text`."""
    def build(folder: Path):
        (folder / "pred.obj").write_text(obj_text)
        rows = np.zeros(4, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
        rows["x"] = np.arange(4) * 0.1
        PlyData([PlyElement.describe(rows, "vertex")]).write(str(folder / "gt.ply"))
        return ["eval", "pred.obj", "--gt", "gt.ply"], ["pred.obj", *words]
    return build


CASES = [
    # the scene folder and its sub-folders
    Case("scene-symlink-loop", scene_symlink_loop),
    Case("scene-not-found", lambda d: (["info", "missing"], ["missing", "not found"])),
    Case("nef-image-folder-symlink-loop", info_fails(loop_as_image_folder, "train_img", "symlink loop")),
    Case("nef-image-folder-broken-link", info_fails(broken_image_folder, "train_img", "not a folder")),
    Case("nef-first-image-wrong-size", info_fails(wrong_sized_first_image, "train_img/r_0.png",
                                                  f"20x{SIZE}")),
    # files outside the scene folder
    Case("file-path-absolute-outside", info_fails(edited(frame_value(0, "file_path", "/etc/passwd")),
                                                  "/etc/passwd", "outside")),
    Case("file-path-dotdot-outside", info_fails(outside_file_path, "elsewhere/x.png", "outside",
                                                ALLOW_OUTSIDE)),
    Case("image-linked-outside", info_fails(image_linked_outside, "r_1.png", "elsewhere.png", "outside")),
    Case("edge-folder-linked-outside", info_fails(edge_folder_linked_outside, "edge_Canny", "outside")),
    Case("emap-rgb-path-outside", info_fails(lambda d: emap(d, frame_value(0, "rgb_path", "../../x.png")),
                                             "x.png", "outside")),
    Case("neus-image-linked-outside", info_fails(neus_image_linked_outside, "000.png", "outside")),
    # absurd cameras
    Case("translation-1e30", nerf_edit(matrix_entry(1, 0, 3, 1e30), "frame 1", "from the origin")),
    Case("pose-last-row-zero", nerf_edit(pose_row(2, 3, [0, 0, 0, 0]), "frame 2", "last row")),
    Case("focal-1e-9", nerf_edit(updated(fl_x=1e-9), "frame 0", "field of view")),
    Case("focal-1e30", nerf_edit(updated(fl_x=1e30), "frame 0", "field of view")),
    Case("angle-1e-12", nerf_edit(updated(camera_angle_x=1e-12), "frame 0", "field of view")),
    Case("intrinsics-infinite", nerf_edit(intrinsics(1, [[INF, 0, 7.5], [0, 20, 7.5], [0, 0, 1]]),
                                          "frames[1].camera_intrinsics[0][0]", "Infinity")),
    Case("intrinsics-last-row", nerf_edit(intrinsics(0, [[20, 0, 7.5], [0, 20, 7.5], [0, 0, 0]]),
                                          "frame 0", "not of the form")),
    Case("principal-point-far-outside", nerf_edit(updated(fl_x=20.0, cx=1e5), "principal point")),
    Case("nerf-image-size-huge", nerf_edit(updated(w=100000, h=100000), "image size 100000x100000")),
    Case("emap-focal-huge", emap_edit(lambda m: m["frames"][0]["intrinsics"][0].__setitem__(0, 1e30),
                                      "frame 0", "field of view")),
    Case("emap-size-huge", emap_edit(updated(width=100000, height=100000), "image size")),
    Case("emap-worldtogt-singular", emap_edit(updated(worldtogt=[[0] * 4] * 3 + [[0, 0, 0, 1]]),
                                              "worldtogt", "not invertible")),
    Case("emap-aabb-inverted", emap_edit(updated(scene_box={"aabb": [[1, 1, 1], [-1, -1, -1]]}),
                                         "scene_box.aabb")),
    Case("emap-image-missing", emap_image_missing),
    # sizes that grow with a file's numbers
    Case("too-many-views", nerf_edit(lambda m: m.update(frames=m["frames"][:1] * 10001), "10001 views")),
    Case("duplicate-views", info_fails(edited(lambda m: m["frames"].__setitem__(1, m["frames"][0])),
                                       "scene", "2 views are named 'r_0'")),
    Case("neus-object-array", neus_cameras(with_object_array)),
    Case("neus-array-bomb", neus_cameras(with_huge_array)),
    Case("colmap-unknown-camera-id", colmap_with_unknown_camera),
    # damaged images: refused before any map is written
    Case("truncated-png", edges_with_damaged_image(truncated_png)),
    Case("truncated-jpeg", edges_with_damaged_image(truncated_jpeg)),
    Case("png-declaring-30000x30000", edges_with_damaged_image(png_declaring_a_huge_size)),
    # options
    Case("downscale-zero", with_options("--downscale", "0")),
    Case("downscale-negative", with_options("--downscale", "-3")),
    Case("downscale-leaves-no-pixels", with_options("--downscale", "1000")),
    Case("background-not-a-colour", with_options("--background", "red")),
    Case("init-one-view-triangulation", lambda d: (["init", nerf(d, frames=1), "--method", "triangulate"],
                                                   ["triangulation needs at least 2 views"])),
    Case("init-uniform-count-zero", with_options("--uniform-count", "0", command="init")),
    Case("init-match-neighbours-huge", with_options("--match-neighbours", "100000", command="init")),
    Case("make-scene-size-huge", make_scene("--size", "100000")),
    Case("make-scene-views-huge", make_scene("--views", "100000")),
    Case("make-scene-noise-nan", make_scene("--image-noise", "nan")),
    # predictions
    Case("eval-line-of-a-million-units", evaluated("v 0 0 0\nv 1000000 0 0\nl 1 2\n", "10,000,000")),
    Case("eval-coordinate-1e300", evaluated("v 0 0 0\nv 1e300 0 0\nl 1 2\n", "coordinate")),
    Case("eval-coordinate-infinite", evaluated("v 0 0 0\nv inf 0 0\nl 1 2\n", "NaN or infinite")),
]


@pytest.mark.parametrize("case", cases_as_params(CASES))
def test_bad_scene_input_fails_cleanly(case, tmp_path):
    assert_fails_cleanly(case, tmp_path)


def test_the_table_covers_the_issue():
    assert len(CASES) >= 30 and len({case.name for case in CASES}) == len(CASES)


# --- results that used to be silently wrong ------------------------------------------------------


def test_edge_maps_of_a_changed_image_are_recomputed(tmp_path):
    root = nerf(tmp_path)
    first = ensure_edge_maps(load_scene(root), SobelDetector(), progress=False)
    assert first.computed == 3
    assert ensure_edge_maps(load_scene(root), SobelDetector(), progress=False).computed == 0
    write_png(root / "train" / "r_1.png", channels=1)  # other pixels, same name and size
    changed = load_scene(root)
    again = ensure_edge_maps(changed, SobelDetector(), progress=False)
    assert again.computed == 3 and again.folder != first.folder
    expected = SobelDetector().detect(changed.load_image(1))
    np.testing.assert_allclose(changed.load_edge_map(1, "sobel"), expected, atol=1 / 255)


def test_edge_maps_depend_on_the_background(tmp_path):
    root = nerf(tmp_path)
    write_png(root / "train" / "r_0.png", channels=4)
    black = ensure_edge_maps(load_scene(root), SobelDetector(), progress=False)
    white = ensure_edge_maps(load_scene(root, background=(1.0, 1.0, 1.0)), SobelDetector(), progress=False)
    assert white.computed == 3 and white.folder != black.folder


@pytest.mark.parametrize("manifest", ["[]", "{", '{"views": "many"}'])
def test_a_broken_edge_manifest_does_not_matter(tmp_path, manifest):
    root = nerf(tmp_path)
    run = ensure_edge_maps(load_scene(root), SobelDetector(), progress=False)
    (run.folder / "manifest.json").write_text(manifest)
    assert ensure_edge_maps(load_scene(root), SobelDetector(), progress=False).computed == 0


def test_a_truncated_jpeg_is_refused_not_half_decoded(tmp_path):
    """OpenCV decodes a JPEG cut short, greying what is missing, and only prints a libjpeg
    warning: the image must fail, named, before it is decoded."""
    root = nerf(tmp_path, lambda meta: meta.update(w=64, h=64))
    for i in range(3):
        random_image(root / "train" / f"r_{i}.png")
    (root / "train" / "r_2.png").unlink()
    cut = random_image(root / "train" / "r_2.jpg")
    truncated(cut)
    scene = load_scene(root)
    with pytest.raises(InputError, match="truncated JPEG"):
        scene.load_image(2)
    assert list(scene.damaged) == [cut] and "JPEG" in scene.damaged[cut]
    with pytest.raises(InputError) as info:
        read_raw(cut)
    assert info.value.path == cut


def test_every_truncation_of_png_and_jpeg_files_is_found(tmp_path):
    for suffix in (".png", ".jpg"):
        whole = random_image(tmp_path / f"whole{suffix}", size=32).read_bytes()
        cut = tmp_path / f"cut{suffix}"
        for length in range(0, len(whole), max(1, len(whole) // 97)):
            cut.write_bytes(whole[:length])
            with pytest.raises(InputError):
                image_info(cut)
        cut.write_bytes(whole + b"appended after the end")  # as motion photos do
        assert image_info(cut).width == 32


def test_image_headers_agree_with_opencv(tmp_path):
    """Size and alpha read from the headers are what OpenCV decodes, palette and tRNS included."""
    from PIL import Image  # a dependency of matplotlib; only for writing the variants

    rng = np.random.default_rng(0)
    grey = rng.integers(0, 256, (12, 20), dtype=np.uint8)
    rgb = np.stack([grey, grey[::-1], 255 - grey], axis=2)
    variants = {
        "L.png": Image.fromarray(grey), "LA.png": Image.fromarray(grey).convert("LA"),
        "RGB.png": Image.fromarray(rgb), "RGBA.png": Image.fromarray(rgb).convert("RGBA"),
        "P.png": Image.fromarray(rgb).convert("P"), "grey.jpg": Image.fromarray(grey),
        "rgb.jpg": Image.fromarray(rgb), "cmyk.jpg": Image.fromarray(rgb).convert("CMYK"),
    }
    for name, image in variants.items():
        image.save(tmp_path / name)
    Image.fromarray(grey).save(tmp_path / "L-tRNS.png", transparency=3)
    Image.fromarray(rgb).save(tmp_path / "RGB-tRNS.png", transparency=(1, 2, 3))
    Image.fromarray(rgb).convert("P").save(tmp_path / "P-tRNS.png", transparency=0)
    Image.fromarray(rgb).save(tmp_path / "progressive.jpg", progressive=True)
    cv2.imwrite(str(tmp_path / "RGBA16.png"), rng.integers(0, 65536, (12, 20, 4), dtype=np.uint16))
    cv2.imwrite(str(tmp_path / "BGRA.webp"), rng.integers(0, 256, (12, 20, 4), dtype=np.uint8))
    for path in sorted(tmp_path.iterdir()):
        decoded = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        info = image_info(path)
        assert (info.width, info.height) == (20, 12), path.name
        assert info.alpha == (decoded.ndim == 3 and decoded.shape[2] == 4), path.name


def test_a_mixed_grey_and_rgba_scene_is_decided_view_by_view(tmp_path):
    root = nerf(tmp_path)
    write_png(root / "train" / "r_0.png", channels=4)
    write_png(root / "train" / "r_2.png", channels=4)
    scene = load_scene(root)
    with pytest.raises(InputError, match="no alpha channel .* 2 of the scene's 3 views") as info:
        scene.load_coverage(1)
    assert info.value.path == root / "train" / "r_1.png"
    assert scene.load_coverage(0).shape == (SIZE, SIZE) and scene.load_mask(2) is not None
    assert scene.masked_views == [0, 2]
    assert "from the images' alpha, but none in 1 of the 3 views (r_1)" in summary(scene)


def test_a_scene_without_masks_says_so(tmp_path):
    scene = load_scene(nerf(tmp_path))
    assert scene.masked_views == [] and scene.load_coverage(1) is None
    assert "masks         none" in summary(scene)


def test_outside_files_are_allowed_on_request(tmp_path, monkeypatch):
    root = image_linked_outside(tmp_path)
    with pytest.raises(InputError, match="outside the scene folder"):
        load_scene(root)
    monkeypatch.setenv(ALLOW_OUTSIDE, "1")
    assert len(load_scene(root)) == 3


def test_a_symlinked_scene_folder_is_fine(tmp_path):
    root = nef(tmp_path)
    os.symlink(root, tmp_path / "link")
    scene = load_scene(tmp_path / "link")
    assert scene.root == root.resolve() and scene.detectors == ["pidinet"]


def test_training_refuses_a_damaged_photo_beside_good_edge_maps(tmp_path):
    """ABC-NEF trains on the maps in train/, yet a cut photo in train_img/ is named and stops the
    run before anything is written (it used to train without a word)."""
    root = nef(tmp_path)
    truncated(root / "train_img" / "r_1.png")
    result = edgedog("train", root, "--out", tmp_path / "run", "--preset", "preview", "--set", "epochs=1",
                     "--set", "init_count=50", "--quiet")
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert "train_img/r_1.png" in result.stderr and "truncated PNG" in result.stderr
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").iterdir())


def test_damaged_views_skip_trains_on_the_other_views_and_says_so(tmp_path):
    """With damaged_views=skip the cut photo's view is left out of training, of the scene's
    fingerprint and of the extraction, and log.json names it; a resume takes the same views."""
    root = nef(tmp_path)
    cut = root / "train_img" / "r_1.png"
    truncated(cut)
    run = tmp_path / "run"
    options = ["--preset", "preview", "--set", "epochs=1", "--set", "init_count=50", "--quiet"]
    result = edgedog("train", root, "--out", run, *options, "--set", "damaged_views=skip")
    assert result.returncode == 0, result.stderr
    assert f"skipped the view of {cut}" in result.stdout and "truncated PNG" in result.stdout
    log = json.loads((run / "log.json").read_text())
    assert list(log["skipped_views"]) == [str(cut)]
    assert (run / "curves.json").is_file()
    resumed = edgedog("train", root, "--out", run, "--resume", "--quiet")
    assert resumed.returncode == 0, resumed.stderr
