"""Picking in the 3D view: what lies under a click, measured in screen space.

The view is a pinhole `Camera` as the renderers draw it (OpenCV axes: x right, y down, z
forward; pixel centres at integers, image row 0 at the top). A curve is picked by the distance
in pixels from the click to its segments, projected after clipping them at the near plane; a
primitive by the distance in pixels to its projected centre. Among those within the tolerance
the nearest on screen wins, and between equally near ones the one in front.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from edgedog.app.inspection import FisherScores

from edgedog.scenes.camera import Camera

TOLERANCE = 6.0
"""Pixels from the click within which a curve or a primitive centre is picked."""
TIE = 0.5
"""Candidates whose screen distances differ by less than this many pixels count as equally near."""


@dataclass(frozen=True)
class Hit:
    """The item picked: its `index`, its `distance` from the click in pixels, and its camera
    `depth` (z) where it is nearest to the click."""

    index: int
    distance: float
    depth: float


def to_camera(camera: Camera, points: np.ndarray) -> np.ndarray:
    """(..., 3) world points -> (..., 3) camera coordinates (OpenCV axes)."""
    points = np.asarray(points, np.float64)
    return points @ camera.w2c[:3, :3].T + camera.w2c[:3, 3]


def to_pixels(camera: Camera, local: np.ndarray) -> np.ndarray:
    """(..., 3) camera coordinates in front of the camera -> (..., 2) pixel coordinates."""
    K = camera.K
    z = local[..., 2]
    return np.stack([K[0, 0] * local[..., 0] / z + K[0, 1] * local[..., 1] / z + K[0, 2],
                     K[1, 1] * local[..., 1] / z + K[1, 2]], axis=-1)


def segment_distances(point: np.ndarray, starts: np.ndarray, ends: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Distances from a 2D `point` to the 2D segments `starts` -> `ends` (S, 2), and the parameter
    s in [0, 1] of each segment's nearest point (a degenerate segment: its start)."""
    along = ends - starts
    length2 = (along * along).sum(axis=1)
    s = np.where(length2 > 0, ((point - starts) * along).sum(axis=1) / np.where(length2 > 0, length2, 1), 0)
    s = np.clip(s, 0.0, 1.0)
    nearest = starts + s[:, None] * along
    return np.linalg.norm(nearest - point, axis=1), s


def clip_near(local: np.ndarray, near: float) -> tuple[np.ndarray, np.ndarray]:
    """Segments (S, 2, 3) in camera coordinates clipped to z >= near: the clipped segments of those
    that keep a part, and the (S,) mask of which do."""
    z = local[:, :, 2]
    keep = (z >= near).any(axis=1) & np.isfinite(local).all(axis=(1, 2))
    clipped = local[keep].copy()
    z = clipped[:, :, 2]
    for end, other in ((0, 1), (1, 0)):
        behind = z[:, end] < near
        t = (near - z[behind, end]) / (z[behind, other] - z[behind, end])
        start, stop = clipped[behind, end], clipped[behind, other]
        clipped[behind, end] = start + t[:, None] * (stop - start)
        clipped[behind, end, 2] = near
    return clipped, keep


def _best(distances: np.ndarray, depths: np.ndarray, owners: np.ndarray, tolerance: float) -> Hit | None:
    """The nearest candidate on screen within `tolerance`, the front one among ties."""
    within = np.flatnonzero(distances <= tolerance)
    if not len(within):
        return None
    closest = distances[within].min()
    ties = within[distances[within] < closest + TIE]
    best = ties[np.argmin(depths[ties])]
    return Hit(int(owners[best]), float(distances[best]), float(depths[best]))


def pick_segments(camera: Camera, segments: np.ndarray, owners: np.ndarray, pixel, near: float,
                  tolerance: float = TOLERANCE) -> Hit | None:
    """The owner (e.g. the curve) of the segment nearest to `pixel` (x, y) on screen.

    Args: segments (S, 2, 3) world ends; owners (S,) the index each segment belongs to.
    """
    segments = np.asarray(segments, np.float64).reshape(-1, 2, 3)
    if not len(segments):
        return None
    local, keep = clip_near(to_camera(camera, segments), near)
    if not len(local):
        return None
    ends = to_pixels(camera, local)
    distances, s = segment_distances(np.asarray(pixel, np.float64), ends[:, 0], ends[:, 1])
    # Depth at the nearest point: linear in 1/z along the projected segment.
    inverse = (1 - s) / local[:, 0, 2] + s / local[:, 1, 2]
    return _best(distances, 1 / inverse, np.asarray(owners)[keep], tolerance)


def pick_points(camera: Camera, points: np.ndarray, pixel, near: float, tolerance: float = TOLERANCE
                ) -> Hit | None:
    """The point (e.g. a primitive centre) nearest to `pixel` (x, y) on screen, of those in front
    of `near`."""
    local = to_camera(camera, np.asarray(points, np.float64).reshape(-1, 3))
    front = np.flatnonzero((local[:, 2] > near) & np.isfinite(local).all(axis=1))
    if not len(front):
        return None
    distances = np.linalg.norm(to_pixels(camera, local[front]) - np.asarray(pixel, np.float64), axis=1)
    return _best(distances, local[front, 2], front, tolerance)


def panel_pixel(mouse: tuple[float, float], origin: tuple[float, float], scale: tuple[float, float]
                ) -> tuple[float, float]:
    """The view's pixel coordinates (centres at integers) under the mouse at `mouse` points, for a
    view drawn from `origin` (points) at `scale` framebuffer pixels per point."""
    return ((mouse[0] - origin[0]) * scale[0] - 0.5, (mouse[1] - origin[1]) * scale[1] - 0.5)


def pixel_point(pixel: tuple[float, float], origin: tuple[float, float], scale: tuple[float, float]
                ) -> tuple[float, float]:
    """The inverse of `panel_pixel`: where on screen (points) a view pixel lies."""
    return (origin[0] + (pixel[0] + 0.5) / scale[0], origin[1] + (pixel[1] + 0.5) / scale[1])


def chain_segments(chains: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Every chain's consecutive vertex pairs (S, 2, 3), and the (S,) index of the chain of each."""
    pieces = [np.stack([chain[:-1], chain[1:]], axis=1) for chain in chains]
    owners = [np.full(len(piece), i) for i, piece in enumerate(pieces)]
    if not pieces:
        return np.zeros((0, 2, 3)), np.zeros(0, np.int64)
    return np.concatenate(pieces), np.concatenate(owners).astype(np.int64)


def curve_kind(index: int, lines: int, beziers: int) -> str:
    """Whether curve `index` (in `curve_polylines` order: lines, Béziers, polylines) is a 'line',
    a 'Bezier' or a 'polyline'."""
    return "line" if index < lines else "Bezier" if index < lines + beziers else "polyline"


@dataclass(frozen=True)
class CurvePick:
    """A picked curve: its index among the curves shown, its kind and its length (scene units)."""

    index: int
    kind: str
    length: float

    @property
    def text(self) -> str:
        return f"curve {self.index} ({self.kind}): length {self.length:.4g}"


@dataclass(frozen=True)
class PrimitivePick:
    """A picked primitive: its index in the snapshot (of step `step`, publication `key` (run,
    version), `count` primitives), its layer, centre, axis lengths (largest first), opacity, raw
    DoG shape k and (a, t), and its Fisher score (None until known)."""

    index: int
    step: int
    key: tuple[int, int]
    count: int
    layer: str
    position: tuple[float, float, float]
    scales: tuple[float, float, float]
    opacity: float
    k: tuple[float, float]
    shape: tuple[float, float]
    fisher: float | None = None

    @property
    def text(self) -> str:
        """Three lines: which primitive and its Fisher score, its size and opacity, its DoG shape."""
        fisher = "computing..." if self.fisher is None else f"{self.fisher:.3g}"
        scales = " x ".join(f"{s:.3g}" for s in self.scales)
        return (f"primitive {self.index} ({self.layer}, step {self.step}): Fisher U {fisher}\n"
                f"  scale {scales}, opacity {self.opacity:.3f}\n"
                f"  k ({self.k[0]:.3g}, {self.k[1]:.3g}): a {self.shape[0]:.3g}, t {self.shape[1]:.3g}")

    def scored(self, fisher: FisherScores) -> PrimitivePick:
        """This pick with its Fisher score when `fisher` holds its snapshot's primitives' (the same
        run and count), else as it is."""
        scores = fisher.matching(self.key[0], self.count)
        return self if scores is None else dataclasses.replace(self, fisher=float(scores[self.index]))


@dataclass(frozen=True)
class Pick:
    """What a click in the 3D view found: the nearest curve and the nearest primitive on screen
    within the tolerance (either may be None), at view `pixel` (x, y)."""

    pixel: tuple[float, float]
    curve: CurvePick | None = None
    primitive: PrimitivePick | None = None

    @property
    def lines(self) -> list[str]:
        """The readout's lines: those of each item found, or why there is none."""
        found = "\n".join(item.text for item in (self.curve, self.primitive) if item is not None)
        return found.split("\n") if found else ["nothing here (click on a curve or a splat's centre)"]
