"""The built-in default scene: a box with exact ground-truth edges, written in the ABC-NEF layout.

A convex polyhedron is drawn exactly without a GL context: a face is visible when it faces the
camera, visible faces never overlap, and an edge is visible when one of its two faces is.
Views lie on a sphere of radius 4 around (0.5, 0.5, 0.5) as in ABC-NEF; the object sits in
[0, 1]^3 so that 1 unit = 1000 mm, as the ABC protocol assumes.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
from plyfile import PlyData, PlyElement

from edgedog.files import default_cache
from edgedog.groundtruth import GT_SPACING, resample_polyline
from edgedog.scenes.camera import OPENGL_TO_OPENCV, Camera, intrinsics, rigid_inverse

NAME = "box"
TARGET = np.array([0.5, 0.5, 0.5])
CAMERA_DISTANCE = 4.0
FOCAL_AT_800 = 1111.11
LIGHTS = np.array([[0.4, 0.5, 0.75], [-0.6, -0.3, 0.2]])  # directions towards the lights
SUBPIXEL_BITS = 4  # cv2 drawing precision: 1/16 px
EDGE_DETECTOR = "exact"  # the edge maps are the true visible edges, drawn 2 px wide

BOX_MIN = np.array([0.2, 0.3, 0.35])
BOX_MAX = np.array([0.8, 0.7, 0.65])
# Corner i has coordinate bits (x, y, z) = (i & 1, i >> 1 & 1, i >> 2 & 1) of min/max.
CORNERS = np.array([[(BOX_MIN, BOX_MAX)[(i >> a) & 1][a] for a in range(3)] for i in range(8)])
FACES = [  # corner indices, counter-clockwise seen from outside, with outward normals
    ((0, 2, 6, 4), (-1, 0, 0)), ((1, 5, 7, 3), (1, 0, 0)),
    ((0, 4, 5, 1), (0, -1, 0)), ((2, 3, 7, 6), (0, 1, 0)),
    ((0, 1, 3, 2), (0, 0, -1)), ((4, 6, 7, 5), (0, 0, 1)),
]
EDGES = sorted({tuple(sorted((f[k], f[(k + 1) % 4]))) for f, _ in FACES for k in range(4)})


def orbit_cameras(views: int, size: int) -> list[Camera]:
    """`views` cameras on a Fibonacci sphere around TARGET, looking at it, +Z world up."""
    f = FOCAL_AT_800 * size / 800
    K = intrinsics(f, f, (size - 1) / 2, (size - 1) / 2)
    cameras = []
    for i in range(views):
        z = 1 - 2 * (i + 0.5) / views
        phi = i * np.pi * (3 - np.sqrt(5))
        r = np.sqrt(1 - z * z)
        center = TARGET + CAMERA_DISTANCE * np.array([r * np.cos(phi), r * np.sin(phi), z])
        forward = (TARGET - center) / np.linalg.norm(TARGET - center)
        up = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
        right = np.cross(forward, up)
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        c2w = np.eye(4)
        c2w[:3, :3] = np.stack([right, down, forward], axis=1)
        c2w[:3, 3] = center
        cameras.append(Camera(K=K, w2c=rigid_inverse(c2w), width=size, height=size))
    return cameras


def _pixels(camera: Camera, points: np.ndarray) -> np.ndarray:
    uv, _ = camera.project(points)
    return np.round(uv * (1 << SUBPIXEL_BITS)).astype(np.int32)


def render_view(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Exact render of the box.

    Returns:
        rgba: (H, W, 4) uint8, grey Lambertian faces on a transparent background.
        edges: (H, W) uint8, the visible box edges as anti-aliased lines, white on black.
    """
    rgba = np.zeros((camera.height, camera.width, 4), np.uint8)
    edges = np.zeros((camera.height, camera.width), np.uint8)
    lights = LIGHTS / np.linalg.norm(LIGHTS, axis=1, keepdims=True)
    visible = set()
    for index, (corners, normal) in enumerate(FACES):
        normal = np.asarray(normal, float)
        if np.dot(normal, camera.center - CORNERS[list(corners)].mean(axis=0)) <= 0:
            continue
        visible.add(index)
        shade = 0.15 + 0.75 * np.clip(lights @ normal, 0, None).sum() / 1.3
        grey = int(round(255 * min(shade, 1.0)))
        cv2.fillConvexPoly(rgba, _pixels(camera, CORNERS[list(corners)]), (grey, grey, grey, 255),
                           lineType=cv2.LINE_AA, shift=SUBPIXEL_BITS)
    for a, b in EDGES:
        faces = [i for i, (c, _) in enumerate(FACES) if a in c and b in c]
        if visible.intersection(faces):
            p, q = _pixels(camera, CORNERS[[a, b]])
            cv2.line(edges, tuple(p), tuple(q), 255, thickness=2, lineType=cv2.LINE_AA,
                     shift=SUBPIXEL_BITS)
    return rgba, edges


def ground_truth_points() -> np.ndarray:
    """(N, 3) the box's edges sampled by the ABC protocol (every GT_SPACING)."""
    return np.concatenate([resample_polyline(CORNERS[[a, b]], GT_SPACING) for a, b in EDGES])


def write_box_scene(folder: Path, views: int = 50, size: int = 400) -> Path:
    """Write the box scene in the ABC-NEF layout into `folder` (created; must not exist).

    Layout: `train_img/<i>.png` RGBA, `train/<i>.png` edge maps, `transforms_train.json`
    (OpenGL camera-to-world, per-frame intrinsics), `gt/<name>_0.005.ply` ground-truth points.
    The folder is built under a temporary name and renamed when complete.
    """
    tmp = folder.with_name(folder.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    (tmp / "train").mkdir(parents=True)
    (tmp / "train_img").mkdir()
    (tmp / "gt").mkdir()
    cameras = orbit_cameras(views, size)
    frames = []
    for i, camera in enumerate(cameras):
        rgba, edges = render_view(camera)
        cv2.imwrite(str(tmp / "train_img" / f"{i}.png"), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
        cv2.imwrite(str(tmp / "train" / f"{i}.png"), edges)
        c2w_gl = rigid_inverse(camera.w2c) @ OPENGL_TO_OPENCV
        frames.append({"file_path": f"./train/{i}", "camera_intrinsics": camera.K.tolist(),
                       "transform_matrix": c2w_gl.tolist()})
    angle_x = 2 * np.arctan(size / (2 * cameras[0].K[0, 0]))
    (tmp / "transforms_train.json").write_text(
        json.dumps({"camera_angle_x": angle_x, "edge_detector": EDGE_DETECTOR, "frames": frames}, indent=1))
    vertices = np.array([tuple(p) for p in ground_truth_points()],
                        dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    gt_file = tmp / "gt" / f"{folder.name}_{GT_SPACING}.ply"
    PlyData([PlyElement.describe(vertices, "vertex")]).write(str(gt_file))
    shutil.rmtree(folder, ignore_errors=True)
    tmp.rename(folder)
    return folder


def builtin_scene_path(cache: Path | None = None) -> Path:
    """The built-in scene's folder, generated on first use."""
    folder = (cache or default_cache()) / "scenes" / NAME
    if not (folder / "transforms_train.json").is_file():
        write_box_scene(folder)
    return folder
