"""The occluding-contour filter of extraction (extract.filter_contours): on an upright cylinder
seen from a sphere of views, points on its rims (edges) are kept and points on the contour lines
of its side (drawn by the views that graze them) are dropped; the hull's normals; scenes
without masks; and the filter in `filter_primitives`."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgedog.curves.config import ExtractConfig
from edgedog.curves.contours import HullSurface, contour_mask, grazing_shares
from edgedog.curves.extract import filter_primitives
from edgedog.diagnosis import RunStages, filter_losses
from edgedog.primitives import EdgePrimitives
from edgedog.synthetic.cameras import TARGET, orbit_cameras

SIZE = 240
RADIUS, BOTTOM, TOP = 0.3, 0.3, 0.7
CELLS = 64


def cylinder_surface(count: int = 4000) -> np.ndarray:
    """(count * 2, 3) points on the cylinder's rims and side, dense enough for its silhouette."""
    angle = np.linspace(0, 2 * np.pi, count, endpoint=False)
    ring = np.stack([TARGET[0] + RADIUS * np.cos(angle), TARGET[1] + RADIUS * np.sin(angle)], axis=1)
    return np.concatenate([np.column_stack([ring, np.full(count, z)]) for z in (BOTTOM, TOP)])


def rim(z: float, count: int = 90) -> np.ndarray:
    angle = np.linspace(0, 2 * np.pi, count, endpoint=False)
    return np.column_stack([TARGET[0] + RADIUS * np.cos(angle), TARGET[1] + RADIUS * np.sin(angle),
                            np.full(count, z)])


def contour_line(camera, side: int, count: int = 20) -> np.ndarray:
    """(count, 3) points of the vertical line where `camera`'s rays graze the cylinder (side ±1)."""
    offset = camera.center[:2] - TARGET[:2]
    distance = np.linalg.norm(offset)
    turn = side * np.arccos(RADIUS / distance)
    heading = np.arctan2(offset[1], offset[0]) + turn
    x, y = TARGET[0] + RADIUS * np.cos(heading), TARGET[1] + RADIUS * np.sin(heading)
    z = np.linspace(BOTTOM + 0.05, TOP - 0.05, count)
    return np.column_stack([np.full(count, x), np.full(count, y), z])


class CylinderScene:
    """What the contour filter reads of a scene: cameras, bounds, masks and edge maps of the cylinder,
    whose maps draw its silhouette's outline and its visible rims."""

    def __init__(self, views: int = 40, masks: bool = True):
        self.cameras = orbit_cameras(views, SIZE)
        self.bounds = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
        self.with_masks = masks
        surface = cylinder_surface()
        self.masks, self.maps = [], []
        for camera in self.cameras:
            uv, _ = camera.project(surface)
            outline = cv2.convexHull(np.rint(uv).astype(np.int32))
            mask = np.zeros((SIZE, SIZE), np.uint8)
            cv2.fillConvexPoly(mask, outline, 1)
            edges = np.zeros((SIZE, SIZE), np.uint8)
            cv2.polylines(edges, [outline], True, 1)
            for z in (BOTTOM, TOP):  # a rim is drawn where the view sees its face
                if (camera.center[2] - z) * (1 if z == TOP else -1) > 0:
                    ring_uv, _ = camera.project(rim(z, 360))
                    cv2.polylines(edges, [np.rint(ring_uv).astype(np.int32)], True, 1)
            self.masks.append(mask > 0)
            self.maps.append(edges.astype(np.float32))

    def __len__(self) -> int:
        return len(self.cameras)

    def camera(self, index: int):
        return self.cameras[index]

    def load_mask(self, index: int):
        return self.masks[index] if self.with_masks else None

    def load_edge_map(self, index: int, detector: str | None = None) -> np.ndarray:
        return self.maps[index]


@pytest.fixture(scope="module")
def scene() -> CylinderScene:
    return CylinderScene()


def grazed_lines(scene: CylinderScene) -> np.ndarray:
    """Contour lines of the views near the equator (those see the side, not along it)."""
    near_equator = [c for c in scene.cameras if abs(c.center[2] - TARGET[2]) < 0.5 * np.linalg.norm(
        c.center - TARGET)]
    return np.concatenate([contour_line(c, side) for c in near_equator[::3] for side in (-1, 1)])


def test_rims_are_kept_and_contours_dropped(scene):
    rims = np.concatenate([rim(BOTTOM), rim(TOP)])
    contours = grazed_lines(scene)
    points = np.concatenate([rims, contours])
    keep = contour_mask(points, HullSurface(scene, CELLS), "test", max_cosine=0.25, max_share=0.5)
    assert keep[:len(rims)].mean() > 0.95
    assert keep[len(rims):].mean() < 0.2


def test_the_hull_normal_is_the_side_and_the_top(scene):
    points = np.array([[TARGET[0] + RADIUS, TARGET[1], TARGET[2]], [TARGET[0], TARGET[1], TOP],
                       [TARGET[0] - RADIUS, TARGET[1], TARGET[2]]])
    normals = HullSurface(scene, CELLS).normals(points)
    assert normals.shape == (3, 1, 3)
    np.testing.assert_allclose(normals[:, 0], [[1, 0, 0], [0, 0, 1], [-1, 0, 0]], atol=0.15)


def test_no_points_no_work(scene):
    assert contour_mask(np.zeros((0, 3)), HullSurface(scene, CELLS), "test", 0.25, 0.5).shape == (0,)


def test_probes_around_a_rim_see_both_faces_and_on_the_side_one(scene):
    surface = HullSurface(scene, CELLS)
    edge = np.array([[TARGET[0] + RADIUS, TARGET[1], TOP]])
    side = np.array([[TARGET[0] + RADIUS, TARGET[1], TARGET[2]]])
    at_edge, on_side = surface.normals(edge, probe=1.5)[0], surface.normals(side, probe=1.5)[0]
    assert at_edge.shape == on_side.shape == (7, 3)
    assert at_edge[:, 2].max() > 0.8 and at_edge[:, 0].max() > 0.8  # the top's normal and the side's
    assert on_side[:, 0].min() > 0.8


def test_probes_keep_rims_where_the_point_normal_alone_loses_them(scene):
    """At a strict share, the rims' own (smoothed) normals are grazed by too many views; the
    probes see the crease and keep them, while the side's contour lines still go."""
    rims = np.concatenate([rim(BOTTOM), rim(TOP)])
    points = np.concatenate([rims, grazed_lines(scene)])
    surface = HullSurface(scene, CELLS)
    alone = contour_mask(points, surface, "test", max_cosine=0.25, max_share=0.2, probe=0.0)
    probed = contour_mask(points, surface, "test", max_cosine=0.25, max_share=0.2, probe=1.0)
    assert alone[:len(rims)].mean() < 0.5 and probed[:len(rims)].mean() > 0.95
    assert probed[len(rims):].mean() < 0.05


def test_undrawn_points_and_points_without_a_normal_are_not_judged(scene):
    points = np.array([[TARGET[0], TARGET[1], TARGET[2] + 5.0], [TARGET[0] + RADIUS, TARGET[1], TARGET[2]]])
    normals = np.array([[[0.0, 0.0, 1.0]], [[0.0, 0.0, 0.0]]])
    np.testing.assert_array_equal(grazing_shares(points, normals, scene, "test", 0.25), [0.0, 0.0])


def test_non_finite_and_far_points_are_not_judged(scene):
    points = np.array([[np.nan, 0.5, 0.5], [np.inf, 0.5, 0.5], [0.5, 0.5, -np.inf], [50.0, 50.0, 50.0]])
    with np.errstate(invalid="ignore"):
        keep = contour_mask(points, HullSurface(scene, CELLS), "test", 0.25, 0.5, probe=1.0)
    assert keep.tolist() == [True, True, True, True]


def test_a_scene_without_masks_is_not_filtered():
    scene = CylinderScene(views=8, masks=False)
    assert contour_mask(rim(TOP), HullSurface(scene, CELLS), "test", 0.25, 0.5) is None


def test_filter_primitives_runs_it_last_and_counts_it(scene):
    points = np.concatenate([rim(TOP), grazed_lines(scene)])
    count = len(points)
    primitives = EdgePrimitives(points, np.tile([0.0, 0.0, 1.0], (count, 1)), np.full(count, 3.0),
                                np.ones(count), np.ones((count, 2)))
    config = ExtractConfig(filter_projection=False, filter_silhouette=False, filter_outliers="off",
                           contour_hull_cells=CELLS)  # the contour filter is on by default
    counts: dict[str, int] = {}
    kept = filter_primitives(primitives, config, scene, "test", counts)
    assert counts["after_contours"] == len(kept) < count
    assert len(kept) >= 0.95 * len(rim(TOP))
    off: dict[str, int] = {}
    without = ExtractConfig(filter_projection=False, filter_silhouette=False, filter_outliers="off",
                            filter_contours=False)
    filter_primitives(primitives, without, scene, "test", off)
    assert "after_contours" not in off


def test_the_diagnosis_names_the_filter_only_where_the_extraction_ran_it(scene):
    """An extract.json written before the contour filter existed has no `filter_contours`: the
    filter did not run, and the diagnosis does not name it."""
    points = np.concatenate([rim(TOP), grazed_lines(scene)])
    count = len(points)
    primitives = EdgePrimitives(points, np.tile([0.0, 0.0, 1.0], (count, 1)), np.full(count, 3.0),
                                np.ones(count), np.ones((count, 2)))
    others_off = {"filter_projection": False, "filter_silhouette": False, "contour_hull_cells": CELLS}

    def losses(config: dict) -> np.ndarray:
        stages = RunStages(points, primitives, None, config, 0, None)
        return filter_losses(np.arange(count), stages, scene, "test")
    before = losses(others_off)
    assert set(before) == {"outliers"}
    ran = losses({**others_off, "filter_contours": True})
    dropped = ~contour_mask(points, HullSurface(scene, CELLS), "test", 0.25, 0.5, probe=1.0)  # the defaults
    assert dropped[len(rim(TOP)):].mean() > 0.5
    np.testing.assert_array_equal(ran == "contours", dropped)
