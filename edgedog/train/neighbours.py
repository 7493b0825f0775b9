"""The k nearest other points of each point: a k-d tree on the host, blocked distances on a GPU.

The direction loss asks for the primitives' neighbours at every fifth step late in a run. On a
GPU, a k-d tree means copying the centres to the host, waiting for the GPU's queue to drain and
building the tree there (milliseconds); the blocked search stays on the device as a few matrix
products and partial sorts, but its work grows with the square of the count, so above
`DEVICE_SEARCH_LIMIT` points the tree is faster again. Both are exact: the blocked search takes
a few more candidates than asked for by the fast squared distances |a|^2 + |b|^2 - 2 a.b, whose
rounding could misorder near ties, and ranks them by exact float64 distances.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial import cKDTree

BLOCK_ELEMENTS = 1 << 26
"""At most this many point pairs (256 MiB of float32 distances) are held at once."""
EXTRA_CANDIDATES = 8
"""Candidates beyond k ranked by the exact distances."""
DEVICE_SEARCH_LIMIT = 12_000
"""Up to this many points a GPU searches by distances, above it by the host's tree. Measured on an
H200 (docs/notes/2026-11-27-gpu-seeds.md, this search with float64 distances throughout): 4.9
against 6.8 ms at 10,000 points, 19 against 9 ms at 20,000."""


def nearest_neighbours(points: torch.Tensor, k: int) -> torch.Tensor:
    """(N, k') int64 indices of each point's k' = min(k, N - 1) nearest other points, nearest
    first: `blocked_nearest` on the points' device for at most `DEVICE_SEARCH_LIMIT` points off
    the CPU, else a k-d tree on the host (its threads are torch's), returned on the host.

    Args:
        points: (N, 3) float positions, N >= 2.
    """
    if points.device.type != "cpu" and len(points) <= DEVICE_SEARCH_LIMIT:
        return blocked_nearest(points, k)
    host = points.detach().cpu().numpy()
    k = min(k, len(host) - 1)
    # The query's threads are torch's: a run given one core (a batch) keeps to one.
    _, index = cKDTree(host).query(host, k=k + 1, workers=torch.get_num_threads())
    return torch.from_numpy(np.asarray(index)[:, 1:].astype(np.int64))


def blocked_nearest(points: torch.Tensor, k: int, block_elements: int = BLOCK_ELEMENTS) -> torch.Tensor:
    """`nearest_neighbours` by distances to every point, a block of rows at a time, on the
    points' device. A point is never its own neighbour (a copy of it at distance 0 may be).

    Args:
        points: (N, 3) float positions, N >= 2.
        block_elements: at most this many distances per block (a block has at least one row).
    Returns:
        (N, min(k, N - 1)) int64; among equal distances the lower index comes first.
    """
    n = len(points)
    k = min(k, n - 1)
    candidates = min(k + EXTRA_CANDIDATES, n - 1)
    exact = points.detach().to(torch.float64)
    centred = (exact - exact.mean(0)).to(torch.float32)  # smaller norms: less cancellation
    norms = (centred * centred).sum(1)
    rows_per_block = max(1, block_elements // n)
    found = []
    for start in range(0, n, rows_per_block):
        rows = torch.arange(start, min(start + rows_per_block, n), device=points.device)
        squared = norms[rows, None] + norms[None, :] - 2 * (centred[rows] @ centred.T)
        squared[torch.arange(len(rows), device=points.device), rows] = torch.inf  # not itself
        pool = torch.topk(squared, candidates, dim=1, largest=False).indices  # (B, candidates)
        # Exact ranking: by float64 distance, then by index (sort by index first, then stably).
        pool = torch.sort(pool, dim=1).values
        offsets = exact.index_select(0, pool.reshape(-1)).reshape(*pool.shape, 3) - exact[rows, None, :]
        order = torch.sort((offsets * offsets).sum(-1), dim=1, stable=True).indices[:, :k]
        found.append(torch.gather(pool, 1, order))
    return torch.cat(found)
