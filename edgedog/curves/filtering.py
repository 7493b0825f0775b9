"""Point filters, each returning a keep mask (N,): EdgeGaussians' three (opacity, projection,
statistical outliers), a silhouette test of our own, and the chains that the outlier filter
spares."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from edgedog.curves.grouping import candidate_links
from edgedog.errors import InputError
from edgedog.scenes import Scene


def opacity_mask(opacity: np.ndarray, min_opacity: float) -> np.ndarray:
    """Keep the primitives with opacity (N,) above `min_opacity`."""
    return opacity > min_opacity


def view_weights(points: np.ndarray, opacity: np.ndarray, opacity_dirs: np.ndarray,
                 centres: np.ndarray) -> np.ndarray:
    """(V, N) each primitive's opacity in each view divided by its largest over the views: 1
    where it is drawn most, near 0 where its view-dependent opacity hides it (training's
    `edgedog.train.view_opacity.relative_opacity`, from what primitives.ply holds: the largest
    opacity instead of the logit a).

    Args:
        points: (N, 3) centres; opacity: (N,) the largest opacity over the views of `centres`
            (V, 3), as primitives.ply holds it; opacity_dirs: (N, 3) b, the logit in a view being
            a + b . d (d the unit direction to its camera).
    """
    offsets = centres[:, None, :] - points[None, :, :]
    unit = offsets / np.maximum(np.linalg.norm(offsets, axis=2, keepdims=True), 1e-12)
    tilt = np.einsum("vnk,nk->vn", unit, opacity_dirs)  # b . d per view
    clipped = np.clip(opacity, 1e-12, 1 - 1e-12)
    largest = np.log(clipped) - np.log1p(-clipped)  # the largest logit, a + max over views of b . d
    logits = largest[None, :] - (tilt.max(axis=0)[None, :] - tilt)
    return 1.0 / (1.0 + np.exp(-logits)) / clipped[None, :]


def chain_mask(points: np.ndarray, directions: np.ndarray, radius: float, min_extent: float,
               min_cos: float) -> np.ndarray:
    """(N,) True for the points (N, 3) on a chain: a connected set linked by candidate links
    (`grouping.candidate_links`: within `radius`, directions (N, 3) and offset parallel within
    |cos| > `min_cos`) whose bounding box's diagonal is at least `min_extent`.

    An edge that training holds with few primitives (one that few views see) is such a chain, and
    the statistical outlier filter, whose statistics follow the density of the other edges, takes
    it for outliers; a scattered floater is not one.
    """
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    pairs, _ = candidate_links(points, directions, radius, min_cos)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points), len(points)))
    count, labels = connected_components(graph, directed=False)
    low = np.full((count, 3), np.inf)
    high = np.full((count, 3), -np.inf)
    np.minimum.at(low, labels, points)
    np.maximum.at(high, labels, points)
    return (np.linalg.norm(high - low, axis=1) >= min_extent)[labels]


def mean_edge_values(points: np.ndarray, scene: Scene, detector: str,
                     weights: np.ndarray | None = None) -> np.ndarray:
    """Edge-map value under each point (N, 3), averaged over all views of the scene; (N,).

    A view that does not see a point contributes 0, so points seen by few views score low.
    `weights` (V, N), e.g. `view_weights`: a weighted mean instead, each view counting by its
    weight (a view the point projects outside of still counts its weight, with 0).
    """
    total = np.zeros(len(points))
    for i in range(len(scene)):
        pixels, inside = scene.camera(i).pixels(points)
        edge_map = scene.load_edge_map(i, detector)
        values = edge_map[pixels[inside, 1], pixels[inside, 0]]
        total[inside] += values if weights is None else weights[i, inside] * values
    if weights is None:
        return total / max(len(scene), 1)
    return total / np.maximum(weights.sum(axis=0), 1e-12)


def projection_mask(points: np.ndarray, scene: Scene, detector: str, min_edge_value: float,
                    weights: np.ndarray | None = None) -> np.ndarray:
    """Keep the points (N, 3) whose mean edge value over all views (weighted by `weights` (V, N)
    if given) is above `min_edge_value`."""
    return mean_edge_values(points, scene, detector, weights) > min_edge_value


def pixels_outside_masks(points: np.ndarray, scene: Scene) -> np.ndarray | None:
    """Largest distance, in pixels, by which each point (N, 3) lands outside the object's mask
    over the views whose image it lands in; (N,), 0 for a point inside every mask. None when
    the scene has no masks. A view whose image cannot be read is left out, as in training."""
    outside = np.zeros(len(points))
    for i in range(len(scene)):
        try:
            mask = scene.load_mask(i)
        except InputError:
            continue
        if mask is None:
            return None
        # distance of each background pixel to the nearest object pixel
        distance = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        pixels, inside = scene.camera(i).pixels(points)
        outside[inside] = np.maximum(outside[inside], distance[pixels[inside, 1], pixels[inside, 0]])
    return outside


def silhouette_mask(points: np.ndarray, scene: Scene, max_outside: float) -> np.ndarray | None:
    """Keep the points (N, 3) that land at most `max_outside` pixels outside the object's mask in
    every view: an edge lies on the object's surface, so inside its silhouette from anywhere.
    None when the scene has no masks."""
    outside = pixels_outside_masks(points, scene)
    return None if outside is None else outside <= max_outside


def outlier_mask(points: np.ndarray, neighbours: int = 25, std_ratio: float = 2.0) -> np.ndarray:
    """Statistical outlier removal on points (N, 3), as open3d's remove_statistical_outlier.

    Each point's mean distance to its `neighbours` nearest points (itself included, as open3d
    counts it) is compared with the mean and sample standard deviation of that value over all
    points; points above mean + std_ratio * std are outliers.
    """
    if len(points) <= neighbours:
        return np.ones(len(points), dtype=bool)
    distances, _ = cKDTree(points).query(points, k=neighbours)
    mean_distance = distances.mean(axis=1)
    limit = mean_distance.mean() + std_ratio * mean_distance.std(ddof=1)
    return mean_distance <= limit
