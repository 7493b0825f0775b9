"""The visual hull's carving (edgedog.hull.carve), coarse to fine, against testing every cell's
centre in every view: the same cells on random silhouettes, grids of any size, views that see
only part of the cube, a camera inside it, full, empty and missing masks."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgedog.hull import carve, widened
from edgedog.scenes.camera import Camera
from edgedog.synthetic.cameras import TARGET, orbit_cameras

SIZE = 160


def every_centre(cameras: list[Camera], masks: list[np.ndarray | None], center: np.ndarray, side: float,
                 resolution: int) -> np.ndarray:
    """(R, R, R) bool reference: each cell's centre projected into every view and kept where
    the view's grown mask holds its pixel, or it falls off the image or behind the camera."""
    cell = side / resolution
    steps = (np.arange(resolution) + 0.5) * cell
    centres = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), axis=-1).reshape(-1, 3)
    centres += np.asarray(center) - side / 2
    keep = np.ones(len(centres), bool)
    for camera, mask in zip(cameras, masks):
        if mask is not None:
            pixels, inside = camera.pixels(centres)
            keep[inside] &= widened(mask)[pixels[inside, 1], pixels[inside, 0]]
    return keep.reshape((resolution,) * 3)


def sphere_mask(camera: Camera, radius: float) -> np.ndarray:
    """(H, W) bool disc where a sphere of `radius` around TARGET projects (about)."""
    uv, depth = camera.project(TARGET[None])
    mask = np.zeros((camera.height, camera.width), np.uint8)
    pixels = int(np.ceil(radius / depth[0] * camera.K[0, 0]))
    cv2.circle(mask, tuple(int(v) for v in np.rint(uv[0])), pixels, 1, -1)
    return mask > 0


def blob_mask(rng: np.random.Generator, camera: Camera) -> np.ndarray:
    """(H, W) bool: a sphere's disc with random ellipses added (some cut by the image's border)
    and a small one cut out; for a camera inside the sphere, all but a random ellipse."""
    size = camera.width
    if camera.project(TARGET[None])[1][0] < 0.3:
        mask = np.ones((size, size), np.uint8)
        ellipses = [(0, size // 6, size // 3)]
    else:
        mask = sphere_mask(camera, 0.3).astype(np.uint8)
        ellipses = [(1, size // 12, size // 3)] * int(rng.integers(1, 4)) + [(0, size // 30, size // 12)]
    for value, low, high in ellipses:
        centre = tuple(int(v) for v in rng.integers(0, size, 2))
        axes = tuple(int(v) for v in rng.integers(low, high, 2))
        cv2.ellipse(mask, centre, axes, float(rng.uniform(0, 180)), 0, 360, value, -1)
    return mask > 0


def inside_camera(size: int) -> Camera:
    """A camera at the cube's centre looking along +X: half the cells lie behind it."""
    K = np.array([[size * 0.8, 0, (size - 1) / 2], [0, size * 0.8, (size - 1) / 2], [0, 0, 1]], float)
    R = np.array([[0, 1, 0], [0, 0, -1], [1, 0, 0]], float)  # camera z along world +X
    w2c = np.eye(4)
    w2c[:3, :3], w2c[:3, 3] = R, -R @ TARGET
    return Camera(K=K, w2c=w2c, width=size, height=size)


@pytest.mark.parametrize("seed, resolution", [(0, 48), (1, 37), (2, 64), (3, 5)])
def test_blocks_carve_the_cells_that_every_centre_does(seed, resolution):
    rng = np.random.default_rng(seed)
    cameras = orbit_cameras(12, SIZE, phase=seed) + [inside_camera(SIZE)]
    masks = [blob_mask(rng, camera) for camera in cameras]
    masks[3] = None  # a view without a mask carves nothing
    masks[4] = np.ones((SIZE, SIZE), bool)  # one that holds everything
    side = 1.6  # wider than the views' field at the orbit: part of the cube falls off their images
    expected = every_centre(cameras, masks, TARGET, side, resolution)
    carved = carve(cameras, masks, TARGET, side, resolution).occupied.numpy()
    assert 0 < expected.sum() < expected.size  # the case carves some cells and keeps others
    assert np.array_equal(carved, expected)


def test_a_sphere_is_carved_as_every_centre_does_and_holds_the_sphere():
    """The silhouettes of a sphere: the hull holds it, and the blocks give the same cells."""
    cameras = orbit_cameras(20, SIZE)
    radius = 0.25
    masks = [sphere_mask(camera, radius) for camera in cameras]
    grid = carve(cameras, masks, TARGET, 1.1, 64)
    assert np.array_equal(grid.occupied.numpy(), every_centre(cameras, masks, TARGET, 1.1, 64))
    steps = (np.arange(64) + 0.5) * grid.cell
    centres = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), axis=-1) + grid.origin
    in_sphere = np.linalg.norm(centres - TARGET, axis=-1) < radius
    assert grid.occupied.numpy()[in_sphere].all()


def test_an_empty_mask_carves_every_cell_it_sees():
    cameras = orbit_cameras(4, SIZE)
    masks = [np.zeros((SIZE, SIZE), bool)] + [np.ones((SIZE, SIZE), bool)] * 3
    carved = carve(cameras, masks, TARGET, 1.1, 32).occupied.numpy()
    assert np.array_equal(carved, every_centre(cameras, masks, TARGET, 1.1, 32))
    assert not carved.all()
