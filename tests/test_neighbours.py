"""The direction loss's neighbour search: the blocked distances on any device against the k-d tree."""

import numpy as np
import pytest
import torch
from scipy.spatial import cKDTree

from edgedog.train.neighbours import blocked_nearest, nearest_neighbours

DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


def tree_distances(points: np.ndarray, k: int) -> np.ndarray:
    """(N, k) float64 distances to each point's k nearest other points, by a k-d tree."""
    distances, _ = cKDTree(points).query(points, k=k + 1)
    return distances[:, 1:]


def exact_distances(points: np.ndarray, index: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points.astype(np.float64)[index] - points.astype(np.float64)[:, None], axis=-1)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("offset", [0.0, 1000.0])
def test_blocked_search_finds_the_k_d_trees_neighbours(device, offset):
    """Random centres (a cloud far from the origin too: the fast distances' cancellation), in
    blocks of 37 rows: the same neighbours as the k-d tree, nearest first."""
    rng = np.random.default_rng(0)
    points = (offset + rng.random((1200, 3)) * 0.3).astype(np.float32)
    found = blocked_nearest(torch.from_numpy(points).to(device), 5, block_elements=37 * 1200).cpu().numpy()
    _, expected = cKDTree(points).query(points, k=6)
    assert found.shape == (1200, 5) and found.dtype == np.int64
    np.testing.assert_array_equal(found, expected[:, 1:])


@pytest.mark.parametrize("device", DEVICES)
def test_copies_are_neighbours_and_a_point_never_its_own(device):
    """Densification copies primitives in place: a copy is a neighbour at distance 0, the point
    itself never is, and the distances are the k-d tree's."""
    rng = np.random.default_rng(1)
    points = rng.random((300, 3)).astype(np.float32)
    points[150:160] = points[:10]  # ten exact copies
    found = blocked_nearest(torch.from_numpy(points).to(device), 4, block_elements=64 * 300).cpu().numpy()
    assert not (found == np.arange(300)[:, None]).any()
    assert set(found[:10, 0]) == set(range(150, 160)) and set(found[150:160, 0]) == set(range(10))
    np.testing.assert_array_equal(exact_distances(points, found), tree_distances(points, 4))


@pytest.mark.parametrize("device", DEVICES)
def test_fewer_points_than_neighbours_asked(device):
    points = torch.tensor([[0.0, 0, 0], [1, 0, 0], [3, 0, 0]], device=device)
    found = blocked_nearest(points, 5).cpu()
    assert found.tolist() == [[1, 2], [0, 2], [1, 0]]
    assert nearest_neighbours(points.cpu(), 5).tolist() == found.tolist()


def test_the_host_keeps_the_k_d_tree():
    """On the CPU the search is the k-d tree's, as the runs trained so far were."""
    points = np.random.default_rng(2).random((500, 3)).astype(np.float32)
    _, expected = cKDTree(points).query(points, k=6)
    np.testing.assert_array_equal(nearest_neighbours(torch.from_numpy(points), 5).numpy(), expected[:, 1:])
