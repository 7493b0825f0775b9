"""The built-in box scene: exact ground truth that projects onto its own edge maps."""

from __future__ import annotations

import numpy as np

from edgedog.builtin_scene import CORNERS, EDGES, orbit_cameras, render_view
from edgedog.scenes import load_scene


def test_loads_as_an_abc_nef_style_scene(builtin_scene_dir):
    scene = load_scene(builtin_scene_dir)
    assert scene.format == "nerf" and len(scene) == 50
    assert scene.detectors == ["exact"]
    assert scene.ground_truth is not None
    points = scene.ground_truth.load()
    # 12 box edges, perimeter 4 * (0.6 + 0.4 + 0.3) = 5.2 units sampled every ~5 mm.
    assert 1000 <= len(points) <= 1040
    assert points.min() >= 0 and points.max() <= 1


def test_ground_truth_projects_onto_the_edge_maps_and_inside_the_masks(builtin_scene_dir):
    scene = load_scene(builtin_scene_dir)
    points = scene.ground_truth.load()
    for i in range(0, len(scene), 5):
        camera, edges, mask = scene.camera(i), scene.load_edge_map(i), scene.load_mask(i)
        uv, depth = camera.project(points)
        assert (depth > 0).all()
        x, y = np.round(uv).astype(int).T
        # Silhouette edges sit on the mask border: dilate by one pixel before testing.
        assert mask[np.clip(y, 0, camera.height - 1), np.clip(x, 0, camera.width - 1)].mean() > 0.5
        values = edges[y, x]
        # Every box edge that the camera sees is drawn; hidden ones are not.
        assert values.mean() > 10 * edges.mean()
        assert 0.4 < (values > 0.5).mean() < 0.95


def test_the_camera_sees_the_faces_that_face_it():
    camera = orbit_cameras(50, 200)[0]  # the first view sits near the +Z pole, looking down
    rgba, edges = render_view(camera)
    centre_top = np.array([0.5, 0.5, CORNERS[:, 2].max()])
    uv, _ = camera.project(centre_top[None])
    x, y = np.round(uv[0]).astype(int)
    assert rgba[y, x, 3] == 255 and edges[y, x] == 0  # inside the top face, away from edges
    assert rgba[0, 0, 3] == 0 and edges.max() == 255
    assert len(EDGES) == 12
