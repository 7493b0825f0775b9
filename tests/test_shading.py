"""The shading test of extraction (extract.filter_shading): on an upright cylinder shaded by two
fixed lights and seen from a sphere of views, its rims (edges) keep the same grey value on both
sides in every view that draws them, while the contour lines of its side do not, and only the
contour lines are seen grazing on the visual hull; the sides are told apart in 3D; curves no
view draws are not judged. The drawing-plane test on the same cylinder: its contour lines are
drawn by views along one plane, its rims from all around."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgedog.curve_files import EdgeCurves
from edgedog.curves.config import ExtractConfig
from edgedog.curves.contours import HullSurface
from edgedog.curves.drawing_plane import curve_spreads
from edgedog.curves.shading import (
    consistent_share,
    curve_grazing,
    curve_samples,
    shading_shares,
    side_offsets,
)
from edgedog.scenes.camera import Camera, intrinsics, rigid_inverse
from edgedog.synthetic.cameras import TARGET, orbit_cameras
from edgedog.synthetic.render import TWO_LIGHTS

SIZE = 240
RADIUS, BOTTOM, TOP = 0.3, 0.3, 0.7


def shade_cylinder(camera) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) grey image of the capped cylinder in the built-in scenes' look (two lights, as
    `edgedog make-scene --lighting two-lights` renders; 0 off the object) and its (H, W) bool
    mask, ray-cast pixel by pixel."""
    ys, xs = np.mgrid[0:SIZE, 0:SIZE]
    rays = camera.ray_directions(np.column_stack([xs.ravel(), ys.ravel()]).astype(np.float64))
    origin = camera.center - TARGET
    hit_t = np.full(len(rays), np.inf)
    normal = np.zeros_like(rays)
    a = rays[:, 0] ** 2 + rays[:, 1] ** 2
    b = 2 * (origin[0] * rays[:, 0] + origin[1] * rays[:, 1])
    c = origin[0] ** 2 + origin[1] ** 2 - RADIUS ** 2
    disc = b * b - 4 * a * c
    t_side = np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / np.maximum(2 * a, 1e-12), np.inf)
    z_side = origin[2] + TARGET[2] + t_side * rays[:, 2]
    side = (t_side > 0) & (z_side >= BOTTOM) & (z_side <= TOP)
    hit_t[side] = t_side[side]
    at = origin + t_side[:, None] * rays
    normal[side] = np.column_stack([at[side, 0], at[side, 1], np.zeros(side.sum())]) / RADIUS
    for z, up in ((TOP, 1.0), (BOTTOM, -1.0)):
        t_cap = (z - TARGET[2] - origin[2]) / np.where(np.abs(rays[:, 2]) < 1e-12, 1e-12, rays[:, 2])
        point = origin + t_cap[:, None] * rays
        cap = (t_cap > 0) & (point[:, 0] ** 2 + point[:, 1] ** 2 <= RADIUS ** 2) & (t_cap < hit_t)
        hit_t[cap] = t_cap[cap]
        normal[cap] = [0.0, 0.0, up]
    hit = np.isfinite(hit_t)
    lights = np.array(TWO_LIGHTS) / np.linalg.norm(TWO_LIGHTS, axis=1, keepdims=True)
    light = np.clip(normal @ lights.T, 0, None).sum(axis=1)
    grey = np.where(hit, np.minimum(0.15 + 0.75 / 1.3 * light, 1.0), 0.0).reshape(SIZE, SIZE)
    return np.repeat(grey[..., None], 3, axis=2).astype(np.float32), hit.reshape(SIZE, SIZE)


def looking_at(eye: np.ndarray, target: np.ndarray) -> Camera:
    """A 400 px camera at `eye` looking at `target`, +Z up."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    c2w = np.eye(4)
    c2w[:3, :3] = np.stack([right, np.cross(forward, right), forward], axis=1)
    c2w[:3, 3] = eye
    return Camera(K=intrinsics(500.0, 500.0, 199.5, 199.5), w2c=rigid_inverse(c2w), width=400, height=400)


def rim(z: float, count: int = 90) -> np.ndarray:
    angle = np.linspace(0, 2 * np.pi, count)
    return np.column_stack([TARGET[0] + RADIUS * np.cos(angle), TARGET[1] + RADIUS * np.sin(angle),
                            np.full(count, z)])


def contour_line(camera, side: int) -> np.ndarray:
    """(2, 3) the vertical line where `camera`'s rays graze the cylinder (side ±1), as training
    triangulates a contour: a fixed curve that the neighbouring views also draw."""
    offset = camera.center[:2] - TARGET[:2]
    heading = np.arctan2(offset[1], offset[0]) + side * np.arccos(RADIUS / np.linalg.norm(offset))
    x, y = TARGET[0] + RADIUS * np.cos(heading), TARGET[1] + RADIUS * np.sin(heading)
    return np.array([[x, y, BOTTOM + 0.05], [x, y, TOP - 0.05]])


class ShadedCylinder:
    """What the shading test reads of a scene: cameras, images, masks and edge maps of the
    cylinder, whose maps draw its silhouette's outline and its visible rims."""

    def __init__(self, views: int = 60):
        self.cameras = orbit_cameras(views, SIZE)
        self.bounds = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
        self.images, self.masks, self.maps = [], [], []
        for camera in self.cameras:
            image, mask = shade_cylinder(camera)
            contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
            edges = np.zeros((SIZE, SIZE), np.uint8)
            cv2.polylines(edges, contours, True, 1)
            for z in (BOTTOM, TOP):  # a rim is drawn where the view sees its face
                if (camera.center[2] - z) * (1 if z == TOP else -1) > 0:
                    ring_uv, _ = camera.project(rim(z, 360))
                    cv2.polylines(edges, [np.rint(ring_uv).astype(np.int32)], True, 1)
            self.images.append(image)
            self.masks.append(mask)
            self.maps.append(edges.astype(np.float32))

    def __len__(self) -> int:
        return len(self.cameras)

    def camera(self, index: int):
        return self.cameras[index]

    def load_image(self, index: int) -> np.ndarray:
        return self.images[index]

    def load_mask(self, index: int) -> np.ndarray:
        return self.masks[index]

    def load_edge_map(self, index: int, detector: str | None = None) -> np.ndarray:
        return self.maps[index]


@pytest.fixture(scope="module")
def scene() -> ShadedCylinder:
    return ShadedCylinder()


def equator_contours(scene: ShadedCylinder) -> list[np.ndarray]:
    """Contour lines of the views near the equator (those see the side, not along it)."""
    near_equator = [c for c in scene.cameras
                    if abs(c.center[2] - TARGET[2]) < 0.4 * np.linalg.norm(c.center - TARGET)]
    return [contour_line(c, side) for c in near_equator[::2] for side in (-1, 1)]


def test_rims_keep_their_shading_and_contours_do_not(scene):
    contours = equator_contours(scene)
    curves = EdgeCurves(lines=np.stack(contours), polylines=[rim(BOTTOM), rim(TOP)])
    shares = shading_shares(curve_samples(curves), scene, "test", scene.masks, tolerance=0.02)
    contour_shares, rim_shares = shares[:len(contours)], shares[len(contours):]
    assert np.all(rim_shares >= 0.7), rim_shares
    judged = contour_shares[np.isfinite(contour_shares)]
    assert len(judged) >= 0.8 * len(contours)  # most contours are drawn by enough views to judge
    assert np.all(judged < 0.4), judged
    kept = curves.kept(~(shares < ExtractConfig().shading_min_share))
    assert len(kept.polylines) == 2 and len(kept.lines) == len(contours) - len(judged)


def test_the_contour_lines_are_drawn_from_one_plane_and_the_rims_from_all_around(scene):
    # The drawing-plane test (edgedog.curves.drawing_plane) on the same cylinder: the views that
    # draw a contour line look along the side's tangent plane there, those that draw a rim do not.
    contours = equator_contours(scene)
    curves = EdgeCurves(lines=np.stack(contours), polylines=[rim(BOTTOM), rim(TOP)])
    spreads = curve_spreads(curve_samples(curves), scene, "test")
    contour_spreads = spreads[:len(contours)]
    assert np.isfinite(contour_spreads).all()
    # the maps' lines are a pixel wide and found within a pixel: views up to about 20 degrees off
    # the plane still draw a line (spread about 0.08); the rims' views spread as an edge's do
    assert np.max(contour_spreads) < 0.1, contour_spreads
    assert np.all(spreads[len(contours):] > 0.2), spreads[len(contours):]


def test_only_curves_seen_grazing_on_the_hull_are_judged(scene):
    # The contour lines are seen at grazing incidence by the views that draw them, the rims
    # (where the hull creases) by none: an edge is not judged by its shading at all.
    contours = equator_contours(scene)
    curves = EdgeCurves(lines=np.stack(contours), polylines=[rim(BOTTOM), rim(TOP)])
    config = ExtractConfig()
    grazing = curve_grazing(curve_samples(curves), HullSurface(scene, 64), "test",
                            config.contour_max_cosine, config.contour_probe_cells)
    grazed = grazing >= config.shading_grazing
    assert grazed[:len(contours)].mean() > 0.8 and not grazed[len(contours):].any()


def test_a_face_lies_on_the_same_side_in_every_view():
    # The edge along x between the top face (y > 0, z = 0) and the front face (y = 0, z < 0):
    # every camera in front of and above it sees the top face's point on the same side.
    edge = np.array([[-0.1, 0.0, 0.0], [0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    on_top, signs = np.array([0.0, 0.05, 0.0]), set()
    for eye in ([0.5, -2.0, 2.0], [-1.5, -1.0, 0.5], [1.0, -2.5, 3.0], [0.0, -0.5, 3.0]):
        camera = looking_at(np.array(eye), np.zeros(3))
        uv, across = side_offsets(camera, edge)
        top_uv, _ = camera.project(on_top[None])
        signs.add(bool(np.sign((top_uv[0] - uv[1]) @ across[1]) > 0))
    assert len(signs) == 1


def test_curves_no_view_draws_are_not_judged(scene):
    far = np.array([[[5.0, 5.0, 5.0], [5.2, 5.0, 5.0]]])  # outside every image
    far_samples = curve_samples(EdgeCurves(lines=far))
    assert np.isnan(shading_shares(far_samples, scene, "test", scene.masks, 0.02)).all()
    assert shading_shares(curve_samples(EdgeCurves()), scene, "test", scene.masks, 0.02).shape == (0,)


def test_consistent_share_compares_each_piece_over_the_views():
    # Three pieces of a curve (columns) over four views: the first keeps about 0.5 in two of the
    # three views that see it, the second changes in every view, the background (NaN) is left
    # out, and the third, which fewer than three views see, is not judged.
    values = np.array([[0.5, 0.2, 0.7], [0.51, 0.4, np.nan], [np.nan, 0.6, np.nan], [0.9, 0.8, 0.7]])
    assert consistent_share(values, 0.02) == pytest.approx((2 + 0) / (3 + 4))
    assert np.isnan(consistent_share(values[:, 2:], 0.02))
