"""The edge-vote initialisation: points where the views' edge maps agree, edges seen by few views
included, nothing from empty or broken maps."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgedog.errors import InputError
from edgedog.init import InitSettings, initialize
from edgedog.init.edge_vote import (
    VoteSettings,
    edge_vote_points,
    on_crest,
    surprise,
    thin_to_spacing,
    view_cones,
)
from edgedog.synthetic.cameras import TARGET, orbit_cameras

SIZE = 800
CAMERAS = orbit_cameras(40, SIZE)
PIXEL = 4.0 / (1111.11 * SIZE / 800)
"""World size of a pixel at the cube's centre (cameras 4 units away)."""
CORNERS = np.array([[0.1, 0.1, 0.8], [0.9, 0.1, 0.8], [0.9, 0.9, 0.8], [0.1, 0.9, 0.8]])
BOX = [(CORNERS[i], CORNERS[(i + 1) % 4]) for i in range(4)]
"""A square frame (the top edges of a box) that every view draws, as (start, end) pairs."""
SOLID = np.array([[x, y, z] for x in (0.1, 0.9) for y in (0.1, 0.9) for z in (0.2, 0.8)])
"""The corners of the box whose silhouette is every view's mask."""
HIDDEN = (np.array([0.42, 0.45, 0.5]), np.array([0.58, 0.55, 0.5]))
"""A segment inside the box, drawn only by the views that look at it from +Z (as the floor of a
pocket is seen only from above)."""


def draw(segments, camera) -> np.ndarray:
    """(H, W) float32 map with the segments' projections drawn 1 px wide."""
    image = np.zeros((camera.height, camera.width), np.uint8)
    for start, end in segments:
        samples = np.linspace(start, end, 200)
        uv, _ = camera.project(samples)
        points = np.rint(uv).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(image, [points], False, 255, 1)
    return image.astype(np.float32) / 255


def above(count: int) -> list[int]:
    """The `count` views nearest the +Z direction from the cube's centre."""
    up = [float((c.center - TARGET)[2] / np.linalg.norm(c.center - TARGET)) for c in CAMERAS]
    return list(np.argsort(up)[::-1][:count])


def silhouette(camera) -> np.ndarray:
    """(H, W) bool mask of the box's silhouette."""
    uv, _ = camera.project(SOLID)
    mask = np.zeros((camera.height, camera.width), np.uint8)
    cv2.fillConvexPoly(mask, cv2.convexHull(np.rint(uv).astype(np.int32)), 1)
    return mask > 0


MASKS = [silhouette(c) for c in CAMERAS]


def maps_with_hidden(seeing: list[int]) -> list[np.ndarray]:
    return [draw(BOX + ([HIDDEN] if i in seeing else []), c) for i, c in enumerate(CAMERAS)]


def vote(maps, settings: VoteSettings, count: int = 100_000):
    return edge_vote_points(CAMERAS, maps, MASKS, TARGET, 1.1, count, (0.001, 0.01), settings)


def covered(points: np.ndarray, segment, reach: float) -> float:
    """Share of the segment within `reach` of a point."""
    samples = np.linspace(*segment, 50)
    return float(np.mean([np.min(np.linalg.norm(points - s, axis=1)) < reach for s in samples]))


@pytest.fixture(scope="module")
def hidden_maps():
    return maps_with_hidden(above(6))


def test_every_edge_is_covered(hidden_maps):
    result = vote(hidden_maps, VoteSettings())
    assert min(covered(result.positions, s, 2 * PIXEL) for s in BOX + [HIDDEN]) >= 0.9
    assert result.method == "edge-vote" and np.all(np.isfinite(result.scales))


def test_an_edge_that_six_views_see_is_found_by_their_cone(hidden_maps):
    strict = dict(finest=256, surprise=3.0)
    found = covered(vote(hidden_maps, VoteSettings(cone=6, **strict)).positions, HIDDEN, 2 * PIXEL)
    everyone = vote(hidden_maps, VoteSettings(cone=len(CAMERAS), **strict)).positions
    everyone = covered(everyone, HIDDEN, 2 * PIXEL)
    assert found >= 0.9
    assert everyone <= found - 0.2


def test_the_count_is_a_ceiling(hidden_maps):
    result = vote(hidden_maps, VoteSettings(finest=128), count=300)
    assert len(result) == 300
    assert result.report["cells_agreeing"] > 300


def test_thinning_keeps_a_count_that_follows_the_edge_length():
    rng = np.random.default_rng(0)

    def tube(start, end, count):  # points of a crest 4 mm thick around a segment
        return np.linspace(start, end, count) + rng.normal(0.0, 0.002, (count, 3))

    short = tube([0.0, 0.0, 0.0], [0.3, 0.0, 0.0], 600)
    long = tube([0.0, 0.5, 0.0], [0.4, 0.5, 0.6], 1000)  # 0.72 long, along no axis
    spacing = 0.01
    kept_short, kept_long = (len(thin_to_spacing(points, spacing)) for points in (short, long))
    assert 0.3 / (2 * spacing) <= kept_short <= 0.3 / spacing + 1
    assert abs(kept_long / kept_short - 0.72 / 0.3) < 0.1 * 0.72 / 0.3
    both = np.concatenate([short, long])
    chosen = thin_to_spacing(both, spacing)
    kept = both[chosen]
    assert covered(kept, ([0.0, 0.0, 0.0], [0.3, 0.0, 0.0]), spacing) == 1.0  # no gaps
    gaps = np.linalg.norm(kept[:, None] - kept[None], axis=2) + np.eye(len(kept))
    assert gaps.min() >= spacing
    assert np.all(np.linalg.norm(kept[chosen < len(short), 1:], axis=1) < 0.006)  # off no rim
    assert np.array_equal(thin_to_spacing(both, 0.0), np.arange(len(both)))


def test_a_thinned_vote_still_covers_every_edge(hidden_maps):
    settings = VoteSettings()
    every = vote(hidden_maps, settings)
    spacing = 4 * PIXEL
    thinned = edge_vote_points(CAMERAS, hidden_maps, MASKS, TARGET, 1.1, 100_000, (0.001, 0.01), settings,
                               spacing=spacing)
    assert len(thinned) < len(every) / 2 and thinned.report["spacing"] == spacing
    assert min(covered(thinned.positions, s, spacing) for s in BOX + [HIDDEN]) >= 0.9


def test_empty_and_broken_maps_give_no_points():
    empty = [np.zeros((SIZE, SIZE), np.float32) for _ in CAMERAS]
    assert len(vote(empty, VoteSettings(finest=64))) == 0
    broken = [np.full((SIZE, SIZE), np.nan, np.float32) for _ in CAMERAS]
    assert len(vote(broken, VoteSettings(finest=64))) == 0


def test_masks_carve_what_lies_outside_the_object(hidden_maps):
    masks = [np.zeros((SIZE, SIZE), bool) for _ in CAMERAS]
    result = edge_vote_points(CAMERAS, hidden_maps, masks, TARGET, 1.1, 100_000, (0.001, 0.01),
                              VoteSettings(finest=64))
    assert len(result) == 0


def test_surprise_tells_a_full_cone_from_chance():
    cones = view_cones(CAMERAS, TARGET, 6)
    assert cones.shape == (40, 40) and np.all(cones.sum(axis=1) == 6) and np.all(np.diag(cones) == 1)
    chance = np.full(40, 0.1)
    seen = np.ones((3, 40), bool)
    votes = np.zeros((3, 40), bool)
    votes[0, np.flatnonzero(cones[7])] = True  # every view of one cone, and no other
    votes[1, ::10] = True  # four views scattered over the sphere: what chance gives
    votes[2] = True  # every view
    score = surprise(votes, seen, chance, cones)
    assert score[0] > 3 and score[1] < 1 and score[2] > 20


def test_the_crest_keeps_the_middle_of_a_ridge():
    xs = (np.arange(5) - 2) * 0.1
    points = np.stack([xs, np.zeros(5), np.zeros(5)], axis=1) + 0.05
    score = np.array([1.0, 2.0, 5.0, 2.0, 1.0])
    keep = on_crest(points, score, np.zeros(3), 1.0, 10, reach=2, share=0.8)
    assert keep.tolist() == [False, False, True, False, False]


def test_the_built_in_part_starts_on_its_edges(builtin_scene_dir):
    from edgedog.groundtruth import ground_truth_for
    from edgedog.scenes import load_scene

    scene = load_scene(builtin_scene_dir)
    points = initialize(scene, InitSettings(method="edge-vote"), detector=scene.detectors[0])
    gt = ground_truth_for(scene.root).load()
    to_gt = scene.world_to_gt if scene.world_to_gt is not None else np.eye(4)
    positions = points.positions @ to_gt[:3, :3].T + to_gt[:3, 3]
    from scipy.spatial import cKDTree

    distance = cKDTree(gt).query(positions)[0]
    camera = scene.camera(0)
    pixel = float(np.linalg.norm(camera.center - TARGET)) / camera.K[0, 0]
    assert points.method == "edge-vote" and points.report["requested"] == "edge-vote"
    assert np.mean(distance < 2 * pixel) >= 0.9


def test_a_scene_whose_maps_agree_on_nothing_is_refused(builtin_scene_dir, tmp_path):
    from edgedog.scenes import load_scene

    scene = load_scene(builtin_scene_dir)
    with pytest.raises(InputError, match="agree on no point"):
        initialize(scene, InitSettings(method="edge-vote", vote_surprise=50.0), detector=scene.detectors[0])


def test_a_point_seen_from_few_views_looks_toward_them(hidden_maps):
    import torch

    from edgedog.train.model import EdgeModel

    result = vote(hidden_maps, VoteSettings())
    samples = np.linspace(*HIDDEN, 50)
    near = np.min(np.linalg.norm(result.positions[:, None] - samples[None], axis=2), axis=1) < 2 * PIXEL
    hidden_sight = result.sight[near]
    assert near.sum() >= 10 and np.median(hidden_sight[:, 2]) > 0.5  # the six views above, and chance
    assert np.median(np.linalg.norm(result.sight[~near], axis=1)) < np.median(hidden_sight[:, 2])
    model = EdgeModel.from_points(result, 0.08, (0.0, 0.0), torch.Generator().manual_seed(0), sight_gain=4.0)
    assert torch.allclose(model.opacity_dirs, torch.tensor(4.0 * result.sight, dtype=torch.float32))
    plain = EdgeModel.from_points(result, 0.08, (0.0, 0.0), torch.Generator().manual_seed(0))
    assert torch.all(plain.opacity_dirs == 0)
