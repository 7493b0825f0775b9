"""Each scene loader on well-formed input: conventions (OpenGL -> OpenCV, pixel centres),
intrinsics, downscaling, alpha compositing, edge-map discovery; then the real datasets.

Synthetic scenes are written to pytest's tmp_path; the real ones are read in place from
../shared/data (relative to the repository root) and skipped when that folder is absent.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from edgedog.groundtruth import ground_truth_for
from edgedog.scenes import load_scene
from tests.helpers.paths import shared_path
from tests.helpers.scene_builders import circle_c2ws

FLIP = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenGL <-> OpenCV camera frame


# --- helpers -----------------------------------------------------------------------------------


def w2c_cv(c2w_gl: np.ndarray) -> np.ndarray:
    """OpenCV world-to-camera of an OpenGL camera-to-world."""
    return np.linalg.inv(c2w_gl @ FLIP)


def write_image(path: Path, rgb_or_rgba: np.ndarray) -> Path:
    """Write an RGB(A) or gray uint8 array (channels in RGB order) with OpenCV."""
    path.parent.mkdir(parents=True, exist_ok=True)
    image = rgb_or_rgba
    if image.ndim == 3:
        code = cv2.COLOR_RGBA2BGRA if image.shape[2] == 4 else cv2.COLOR_RGB2BGR
        image = cv2.cvtColor(image, code)
    assert cv2.imwrite(str(path), image)
    return path


def random_image(shape, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, shape, dtype=np.uint8)


# --- NeRF / Blender ----------------------------------------------------------------------------

W, H = 24, 16  # not square, so a swapped width/height shows
ANGLE_X = 0.9
TARGET = np.array([0.3, -0.2, 0.1])
HALF = 128  # alpha of the half-transparent pixel
HALF_PIXEL = (2, 3)  # (row, col)


def nerf_rgba() -> np.ndarray:
    """RGBA image: left half opaque, right half transparent, one half-transparent red pixel."""
    image = random_image((H, W, 4), 0)
    image[..., 3] = 0
    image[:, : W // 2, 3] = 255
    image[HALF_PIXEL] = (255, 0, 0, HALF)
    return image


def make_nerf(root: Path, frames: int = 4, **meta_extra) -> tuple[Path, list[np.ndarray]]:
    c2ws = circle_c2ws(frames, TARGET)
    meta = {"camera_angle_x": ANGLE_X, **meta_extra, "frames": []}
    for i, c2w in enumerate(c2ws):
        write_image(root / "train" / f"r_{i}.png", nerf_rgba())
        meta["frames"].append({"file_path": f"./train/r_{i}", "transform_matrix": c2w.tolist()})
    (root / "transforms_train.json").write_text(json.dumps(meta))
    return root, c2ws


def test_nerf_cameras(tmp_path):
    root, c2ws = make_nerf(tmp_path / "scene")
    scene = load_scene(root)
    assert scene.format == "nerf"
    assert len(scene) == 4 and scene.root == root.resolve()
    assert [v.name for v in scene.views] == ["r_0", "r_1", "r_2", "r_3"]
    assert scene.detectors == []
    focal = 0.5 * W / math.tan(ANGLE_X / 2)
    for i, c2w in enumerate(c2ws):
        cam = scene.camera(i)
        assert (cam.width, cam.height) == (W, H)
        np.testing.assert_allclose(cam.K, [[focal, 0, (W - 1) / 2], [0, focal, (H - 1) / 2], [0, 0, 1]])
        np.testing.assert_allclose(cam.center, c2w[:3, 3], atol=1e-9)
        np.testing.assert_allclose(cam.w2c, w2c_cv(c2w), atol=1e-9)
        np.testing.assert_allclose(cam.R @ cam.R.T, np.eye(3), atol=1e-9)
        # The looked-at point lands on the principal point, in front of the camera...
        uv, depth = cam.project(TARGET[None])
        np.testing.assert_allclose(uv[0], [(W - 1) / 2, (H - 1) / 2], atol=1e-9)
        assert depth[0] == pytest.approx(np.linalg.norm(TARGET - c2w[:3, 3]))
        # ...a point above it (world +Z, the cameras' up) lands higher in the image (smaller v),
        # and one to the camera's right (OpenGL +X) lands further right.
        uv_up = cam.project((TARGET + [0, 0, 0.1])[None])[0][0]
        assert uv_up[1] < (H - 1) / 2 - 0.1
        assert uv_up[0] == pytest.approx((W - 1) / 2, abs=1e-9)
        uv_right = cam.project((TARGET + 0.1 * c2w[:3, 0])[None])[0][0]
        assert uv_right[0] > (W - 1) / 2 + 0.1
        assert uv_right[1] == pytest.approx((H - 1) / 2, abs=1e-9)
        np.testing.assert_allclose(cam.forward, (TARGET - c2w[:3, 3]) / np.linalg.norm(TARGET - c2w[:3, 3]))
    # The bounds hold the point every camera looks at.
    assert scene.bounds.shape == (2, 3)
    assert np.all(scene.bounds[0] < TARGET) and np.all(TARGET < scene.bounds[1])


def test_nerf_intrinsics_variants(tmp_path):
    root, _ = make_nerf(tmp_path / "angles", camera_angle_y=0.7)
    cam = load_scene(root).camera(0)
    assert cam.K[0, 0] == pytest.approx(0.5 * W / math.tan(ANGLE_X / 2))
    assert cam.K[1, 1] == pytest.approx(0.5 * H / math.tan(0.7 / 2))
    root, _ = make_nerf(tmp_path / "explicit", fl_x=30.0, fl_y=31.0, cx=10.0, cy=6.0)
    np.testing.assert_allclose(load_scene(root).camera(1).K, [[30, 0, 10], [0, 31, 6], [0, 0, 1]])


def test_nerf_downscale(tmp_path):
    root, c2ws = make_nerf(tmp_path / "scene", fl_x=30.0, cx=10.0, cy=6.0)
    full = load_scene(root)
    half = load_scene(root, downscale=2)
    assert half.downscale == 2
    for i in range(len(half)):
        cam, ref = half.camera(i), full.camera(i)
        assert (cam.width, cam.height) == (W // 2, H // 2)
        assert cam.K[0, 0] == pytest.approx(ref.K[0, 0] / 2)
        assert cam.K[1, 1] == pytest.approx(ref.K[1, 1] / 2)
        assert cam.K[0, 2] == pytest.approx((10.0 + 0.5) / 2 - 0.5)
        assert cam.K[1, 2] == pytest.approx((6.0 + 0.5) / 2 - 0.5)
        np.testing.assert_array_equal(cam.w2c, ref.w2c)
        # The views keep the cameras of the files on disk.
        assert (half.views[i].camera.width, half.views[i].camera.height) == (W, H)
    assert [c.width for c in half.cameras] == [W // 2] * len(half)
    image = half.load_image(0)
    assert image.shape == (H // 2, W // 2, 3) and image.dtype == np.float32
    assert 0.0 <= image.min() and image.max() <= 1.0
    mask = half.load_mask(0)
    assert mask.shape == (H // 2, W // 2) and mask.dtype == bool
    assert mask[:, : W // 4].all() and not mask[:, W // 4:].any()
    # Centred principal points stay centred: ((W - 1) / 2 + 0.5) / 2 - 0.5 = (W / 2 - 1) / 2.
    root, _ = make_nerf(tmp_path / "centred")
    cam = load_scene(root, downscale=2).camera(0)
    assert (cam.K[0, 2], cam.K[1, 2]) == pytest.approx(((W // 2 - 1) / 2, (H // 2 - 1) / 2))


def test_nerf_images_and_alpha(tmp_path):
    root, _ = make_nerf(tmp_path / "scene")
    written = nerf_rgba().astype(np.float32) / 255.0
    a = HALF / 255.0
    expected = {
        (0.0, 0.0, 0.0): (a, 0.0, 0.0),
        (1.0, 1.0, 1.0): (1.0, 1.0 - a, 1.0 - a),
        None: (1.0, 0.0, 0.0),
    }
    for background, pixel in expected.items():
        scene = load_scene(root, background=background)
        assert scene.background == background
        image = scene.load_image(1)
        assert image.shape == (H, W, 3) and image.dtype == np.float32
        assert 0.0 <= image.min() and image.max() <= 1.0
        np.testing.assert_allclose(image[HALF_PIXEL], pixel, atol=1e-6)
        # Opaque pixels are the file's colours whatever the background...
        np.testing.assert_allclose(image[5:, : W // 2], written[5:, : W // 2, :3], atol=1e-6)
        # ...transparent ones are the background (or the stored colour when alpha is dropped).
        if background is None:
            behind = written[:, W // 2:, :3]
        else:
            behind = np.broadcast_to(background, (H, W // 2, 3))
        np.testing.assert_allclose(image[:, W // 2:], behind, atol=1e-6)
    # The default background is black.
    np.testing.assert_allclose(load_scene(root).load_image(0)[HALF_PIXEL], (a, 0, 0), atol=1e-6)
    mask = load_scene(root).load_mask(2)
    assert mask.shape == (H, W) and mask.dtype == bool
    expected_mask = nerf_rgba()[..., 3] / 255.0 > 0.5
    np.testing.assert_array_equal(mask, expected_mask)


def test_nerf_rgb_images_have_no_mask(tmp_path):
    root, _ = make_nerf(tmp_path / "scene")
    for i in range(4):
        write_image(root / "train" / f"r_{i}.png", random_image((H, W, 3), i))
    scene = load_scene(root)
    assert scene.load_mask(0) is None
    image = scene.load_image(3)
    np.testing.assert_allclose(image, random_image((H, W, 3), 3) / 255.0, atol=1e-6)


def make_nef(root: Path, frames: int = 3) -> Path:
    """ABC-NEF layout: `file_path` names the edge map in train/, the image is in train_img/."""
    meta = {"camera_angle_x": ANGLE_X, "frames": []}
    for i, c2w in enumerate(circle_c2ws(frames, TARGET)):
        write_image(root / "train" / f"{i}.png", random_image((H, W), 10 + i))
        write_image(root / "train_img" / f"{i}.png", nerf_rgba())
        meta["frames"].append({"file_path": f"./train/{i}", "transform_matrix": c2w.tolist()})
    (root / "transforms_train.json").write_text(json.dumps(meta))
    return root


def test_abc_nef_layout(tmp_path):
    root = make_nef(tmp_path / "scene")
    scene = load_scene(root)
    assert scene.format == "nerf"
    assert scene.detectors == ["pidinet"]
    for i, view in enumerate(scene.views):
        assert view.image_path == root.resolve() / "train_img" / f"{i}.png"
        assert view.edge_paths == {"pidinet": root.resolve() / "train" / f"{i}.png"}
    edges = scene.load_edge_map(1)
    assert edges.shape == (H, W) and edges.dtype == np.float32
    np.testing.assert_allclose(edges, random_image((H, W), 11) / 255.0, atol=1e-6)
    np.testing.assert_allclose(scene.load_edge_map(1, "pidinet"), edges)
    assert scene.load_image(1).shape == (H, W, 3)
    assert scene.load_mask(1).sum() == (nerf_rgba()[..., 3] > 127).sum()
    half = load_scene(root, downscale=2).load_edge_map(0)
    assert half.shape == (H // 2, W // 2)


def test_extra_edge_folder_adds_a_detector(tmp_path):
    root = make_nef(tmp_path / "scene")
    for i in range(3):
        write_image(root / "edge_Foo" / f"{i}.png", random_image((H, W, 3), 20 + i))
    scene = load_scene(root)
    assert scene.detectors == ["foo", "pidinet"]
    foo = scene.load_edge_map(2, "foo")
    assert foo.shape == (H, W)
    np.testing.assert_allclose(foo, random_image((H, W, 3), 22).mean(axis=2) / 255.0, atol=1e-6)
    # The default stays the first detector by name.
    np.testing.assert_allclose(scene.load_edge_map(2), foo)
    # A detector missing for one view is not offered.
    (root / "edge_Foo" / "1.png").unlink()
    assert load_scene(root).detectors == ["pidinet"]


# --- EMAP --------------------------------------------------------------------------------------


def test_emap_synthetic(tmp_path):
    root = tmp_path / "00001234"
    c2ws = circle_c2ws(3, TARGET)
    K = np.array([[30.0, 0, 11.5], [0, 29.0, 7.0], [0, 0, 1]])
    world_to_gt = np.array([[0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5], [0, 0, 0.5, 0.5], [0, 0, 0, 1]])
    meta = {
        "camera_model": "OPENCV", "height": H, "width": W, "worldtogt": world_to_gt.tolist(),
        "scene_box": {"aabb": [[-1, -2, -3], [1, 2, 3]]}, "frames": [],
    }
    for i, c2w in enumerate(c2ws):
        name = f"{i}_colors.png"
        write_image(root / "color" / name, random_image((H, W, 3), i))
        write_image(root / "edge_DexiNed" / name, random_image((H, W), 30 + i))
        write_image(root / "edge_PidiNet" / name, random_image((H, W), 40 + i))
        meta["frames"].append(
            {"rgb_path": name, "camtoworld": (c2w @ FLIP).tolist(), "intrinsics": K.tolist()}
        )
    (root / "meta_data.json").write_text(json.dumps(meta))
    scene = load_scene(root)
    assert scene.format == "emap" and len(scene) == 3
    assert scene.detectors == ["dexined", "pidinet"]
    np.testing.assert_array_equal(scene.bounds, [[-1, -2, -3], [1, 2, 3]])
    np.testing.assert_array_equal(scene.world_to_gt, world_to_gt)
    for i, c2w in enumerate(c2ws):
        cam = scene.camera(i)
        np.testing.assert_allclose(cam.K, K)
        np.testing.assert_allclose(cam.w2c, w2c_cv(c2w), atol=1e-9)
        np.testing.assert_allclose(cam.project(TARGET[None])[0][0], [11.5, 7.0], atol=1e-9)
    np.testing.assert_allclose(scene.load_edge_map(2, "dexined"), random_image((H, W), 32) / 255.0, atol=1e-6)
    np.testing.assert_allclose(scene.load_image(1), random_image((H, W, 3), 1) / 255.0, atol=1e-6)


# --- NeuS / IDR --------------------------------------------------------------------------------


def make_neus(root: Path, c2ws, K, scale_mat, sign: float = 1.0) -> Path:
    arrays = {}
    for i, c2w in enumerate(c2ws):
        write_image(root / "image" / f"{i:03d}.png", random_image((H, W, 3), i))
        write_image(root / "mask" / f"{i:03d}.png", np.where(np.arange(W) < W // 3, 255, 0)
                    .astype(np.uint8)[None].repeat(H, 0))
        # world_mat maps the original world; the scene's world is the unit sphere, scale_mat
        # maps it to the original one: P = world_mat @ scale_mat.
        world_mat = np.eye(4)
        world_mat[:3, :4] = sign * 2.0 * K @ w2c_cv(c2w)[:3, :4]  # projective scale is free
        arrays[f"world_mat_{i}"] = world_mat
        arrays[f"scale_mat_{i}"] = scale_mat
    np.savez(root / "cameras_sphere.npz", **arrays)
    return root


NEUS_K = np.array([[30.0, 0.0, 11.0], [0.0, 31.0, 7.5], [0.0, 0.0, 1.0]])
NEUS_SCALE = np.array([[2.0, 0, 0, 0.3], [0, 2.0, 0, -0.2], [0, 0, 2.0, 0.1], [0, 0, 0, 1]])


def test_neus_synthetic(tmp_path):
    c2ws = circle_c2ws(3, TARGET, radius=6.0)
    root = make_neus(tmp_path / "scan", c2ws, NEUS_K, NEUS_SCALE)
    scene = load_scene(root)
    assert scene.format == "neus" and len(scene) == 3
    to_sphere = np.linalg.inv(NEUS_SCALE)
    sphere_points = np.random.default_rng(0).uniform(-0.5, 0.5, (10, 3))
    world_points = sphere_points @ NEUS_SCALE[:3, :3].T + NEUS_SCALE[:3, 3]
    for i, c2w in enumerate(c2ws):
        cam = scene.camera(i)
        np.testing.assert_allclose(cam.K, NEUS_K, atol=1e-9)
        np.testing.assert_allclose(cam.center, (to_sphere @ c2w[:, 3])[:3], atol=1e-9)
        # A point of the unit-sphere frame projects where the original camera sees it.
        reference = w2c_cv(c2w)
        cam_points = world_points @ reference[:3, :3].T + reference[:3, 3]
        expected = cam_points[:, :2] / cam_points[:, 2:] @ NEUS_K[:2, :2].T + NEUS_K[:2, 2]
        np.testing.assert_allclose(cam.project(sphere_points)[0], expected, atol=1e-7)
    mask = scene.load_mask(0)
    assert mask.shape == (H, W) and mask[:, : W // 3].all() and not mask[:, W // 3:].any()
    np.testing.assert_array_equal(scene.bounds, [[-1, -1, -1], [1, 1, 1]])


def test_neus_projection_defined_up_to_a_negative_scale(tmp_path):
    c2ws = circle_c2ws(2, TARGET, radius=6.0)
    root = make_neus(tmp_path / "scan", c2ws, NEUS_K, NEUS_SCALE, sign=-1.0)
    scene = load_scene(root)
    np.testing.assert_allclose(scene.camera(0).K, NEUS_K, atol=1e-9)


# --- COLMAP ------------------------------------------------------------------------------------

CW, CH = 32, 24
COLMAP_PARAMS = {"PINHOLE": [30.0, 28.0, 15.0, 11.0], "SIMPLE_PINHOLE": [30.0, 16.5, 12.5]}


def write_colmap(root: Path, model: str, binary: bool):
    """A COLMAP project with 3 registered images and 12 points; returns what was written."""
    pycolmap = pytest.importorskip("pycolmap")
    rec = pycolmap.Reconstruction()
    camera = pycolmap.Camera.create_from_model_name(1, model, 30.0, CW, CH)
    camera.params = np.asarray(COLMAP_PARAMS[model], dtype=np.float64)
    rec.add_camera_with_trivial_rig(camera)
    poses = []
    for i, c2w in enumerate(circle_c2ws(3, TARGET)):
        w2c = w2c_cv(c2w)
        R, t = w2c[:3, :3], w2c[:3, 3]
        name = "abc"[i] + ".png"
        rec.add_image_with_trivial_frame(
            pycolmap.Image(name=name, camera_id=1, image_id=i + 1),
            pycolmap.Rigid3d(pycolmap.Rotation3d(R), t),
        )
        write_image(root / "images" / name, random_image((CH, CW, 3), i))
        poses.append((R, t))
    rng = np.random.default_rng(1)
    points = TARGET + rng.uniform(-0.3, 0.3, (12, 3))
    colors = rng.integers(0, 256, (12, 3), dtype=np.uint8)
    for xyz, rgb in zip(points, colors):
        rec.add_point3D(xyz, pycolmap.Track(), rgb)
    folder = root / "sparse" if binary else root / "sparse" / "0"
    folder.mkdir(parents=True)
    (rec.write_binary if binary else rec.write_text)(str(folder))
    assert (folder / ("cameras.bin" if binary else "cameras.txt")).is_file()
    return rec.camera(1), poses, points, colors


def _rows_sorted(a: np.ndarray) -> np.ndarray:
    return a[np.lexsort(a.T[::-1])]


@pytest.mark.parametrize("binary", [False, True], ids=["text-sparse0", "binary-sparse"])
@pytest.mark.parametrize("model", ["PINHOLE", "SIMPLE_PINHOLE"])
def test_colmap(tmp_path, model, binary):
    root = tmp_path / "project"
    colmap_camera, poses, points, colors = write_colmap(root, model, binary)
    scene = load_scene(root)
    assert scene.format == "colmap"
    assert [v.name for v in scene.views] == ["a", "b", "c"]
    params = COLMAP_PARAMS[model]
    fx, fy, cx, cy = params if model == "PINHOLE" else (params[0], params[0], params[1], params[2])
    # COLMAP puts the centre of the first pixel at 0.5, edgedog at 0.
    K = [[fx, 0, cx - 0.5], [0, fy, cy - 0.5], [0, 0, 1]]
    for i, (R, t) in enumerate(poses):
        cam = scene.camera(i)
        assert (cam.width, cam.height) == (CW, CH)
        np.testing.assert_allclose(cam.K, K)
        np.testing.assert_allclose(cam.R, R, atol=1e-9)
        np.testing.assert_allclose(cam.t, t, atol=1e-9)
        uv, depth = cam.project(points)
        assert np.all(depth > 0)
        expected = np.asarray(colmap_camera.img_from_cam(points @ R.T + t)) - 0.5
        np.testing.assert_allclose(uv, expected, atol=1e-7)
    assert scene.sfm_points.shape == (12, 3) and scene.sfm_colors.dtype == np.uint8
    order = np.lexsort(scene.sfm_points.T[::-1])
    np.testing.assert_allclose(scene.sfm_points[order], _rows_sorted(points))
    np.testing.assert_array_equal(scene.sfm_colors[order], colors[np.lexsort(points.T[::-1])])
    assert np.all(scene.bounds[0] < TARGET) and np.all(TARGET < scene.bounds[1])
    np.testing.assert_allclose(scene.load_image(2), random_image((CH, CW, 3), 2) / 255.0, atol=1e-6)


# --- real data ---------------------------------------------------------------------------------


@pytest.mark.shared_data
def test_real_abc_nef():
    root = shared_path("abc_nef/00000006")
    scene = load_scene(root)
    assert scene.format == "nerf"
    assert len(scene) == 50
    assert {(v.camera.width, v.camera.height) for v in scene.views} == {(800, 800)}
    assert scene.detectors == ["pidinet"]
    assert ground_truth_for(root) is not None
    cam = scene.camera(0)
    np.testing.assert_allclose(cam.K[:2, 2], [399.5, 399.5])
    assert cam.K[0, 0] == pytest.approx(1111.11, abs=0.01)
    # Cameras on a sphere of radius 4, looking at the object.
    radii = [np.linalg.norm(c.center) for c in scene.cameras]
    np.testing.assert_allclose(radii, 4.0, rtol=0.05)
    assert all(np.dot(c.forward, -c.center) > 0.9 * np.linalg.norm(c.center) for c in scene.cameras)
    edges = scene.load_edge_map(0)
    assert edges.shape == (800, 800) and 0.0 <= edges.min() and edges.max() <= 1.0
    assert scene.load_mask(0).any()


@pytest.mark.shared_data
def test_real_abc_emap():
    root = shared_path("abc_emap/data/00004926")
    scene = load_scene(root)
    assert scene.format == "emap"
    assert len(scene) == 50
    assert scene.detectors == ["dexined", "pidinet"]
    assert ground_truth_for(root) is not None
    assert (scene.camera(0).width, scene.camera(0).height) == (800, 800)


@pytest.mark.shared_data
def test_real_dtu():
    root = shared_path("dtu_scan37")
    scene = load_scene(root)
    assert scene.format == "neus"
    assert len(scene) == 49
    assert {(v.camera.width, v.camera.height) for v in scene.views} == {(1600, 1200)}
    assert all(v.mask_path is not None for v in scene.views)
    # The object sits in the unit sphere, in front of every camera.
    for cam in scene.cameras:
        uv, depth = cam.project(np.zeros((1, 3)))
        assert depth[0] > 0 and 0 <= uv[0, 0] < 1600 and 0 <= uv[0, 1] < 1200
    small = load_scene(root, downscale=4)
    cam = small.camera(0)
    assert (cam.width, cam.height) == (400, 300)
    assert cam.K[0, 0] == pytest.approx(scene.camera(0).K[0, 0] / 4)
    image = small.load_image(0)
    assert image.shape == (300, 400, 3) and image.dtype == np.float32
    mask = small.load_mask(0)
    assert mask.shape == (300, 400) and mask.dtype == bool and mask.any() and not mask.all()
