"""Where a map draws the object's outline, measured and corrected against the object masks.

Maps made from RGBA renders with the alpha dropped (as the ABC-NEF and EMAP maps are) see the
object grown by its anti-aliased rim: straight-alpha PNGs keep the full object colour under
partial alpha. Their silhouette bands then peak outside the outline (DexiNed on 00004926:
+1.2 px), and a model fitted to them grows outwards by 2-3 mm on every side. The masks
(alpha or mask files) are an input of the scene, not ground truth, so the offset is measured
on the training views themselves: the mean map value against the signed distance to the
mask's 0.5-coverage contour peaks at the offset. The correction pulls the map inwards by that
offset near the outline and leaves it alone further inside.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from edgedog.edges.calibration import parabola_vertex

SUBPIXEL = 4
"""Upsampling of the coverage before its distance transform: the contour to a quarter pixel."""

PROFILE_RANGE_PX = 4.0
"""Signed distances from the outline over which the map's mean profile is taken."""

PROFILE_BIN_PX = 0.1


@dataclass(frozen=True)
class Outline:
    """An object mask's outline in one view, at the resolution of its coverage.

    Attributes:
        distance: (H, W) float32 signed distance in px to the 0.5-coverage contour, > 0 outside.
        normal: (H, W, 2) float32 unit outward normal (x, y), the distance's gradient.
        within: both hold only this far from the contour (px; beyond it the distance is at least
            `within`, the normal meaningless); None: everywhere.
    """

    distance: np.ndarray
    normal: np.ndarray
    within: float | None = None

    @classmethod
    def from_coverage(cls, coverage: np.ndarray, within: float | None = None) -> Outline:
        """From an (H, W) coverage in [0, 1] (anti-aliased alpha or a mask).

        `within`: how far from the contour (px) the distance is used; None: everywhere. With it,
        the distance transforms run only on the object's box widened past `within` (the costly
        part: two transforms of the view at SUBPIXEL^2 its pixels), which changes no value
        within `within` of the contour.
        """
        coverage = np.asarray(coverage, np.float32)
        height, width = coverage.shape
        top, bottom, left, right = _reach_box(coverage, within)
        # Pixels off the box are outside the object and farther than `within` from it.
        distance = np.full((height, width), 0.0 if within is None else within + 1.0, np.float32)
        distance[top:bottom, left:right] = _signed_distance(coverage[top:bottom, left:right])
        # The gradient over the whole view, as without a box: OpenCV's vectorised filters round
        # the last columns of a row in another order, so a box's edges would move its last bits.
        gx = cv2.Sobel(distance, cv2.CV_32F, 1, 0, ksize=3)
        gy = cv2.Sobel(distance, cv2.CV_32F, 0, 1, ksize=3)
        norm = np.maximum(np.hypot(gx, gy), 1e-6)
        return cls(distance, np.stack([gx / norm, gy / norm], axis=-1), within)


def _reach_box(coverage: np.ndarray, within: float | None) -> tuple[int, int, int, int]:
    """(top, bottom, left, right) of the pixels that can lie within `within` px of the contour,
    plus what the box's own edges disturb (2 px of the upsampling's support, 1 px of the
    gradient's). The whole view for None or a coverage without any object pixel."""
    height, width = coverage.shape
    # Only pixels over half covered make upsampled pixels over half: faint noise in a mask
    # does not widen the box.
    covered = coverage > 0.5
    rows, cols = np.nonzero(covered.any(axis=1))[0], np.nonzero(covered.any(axis=0))[0]
    if within is None or len(rows) == 0:
        return 0, height, 0, width
    pad = int(np.ceil(within)) + 3
    return (max(0, rows[0] - pad), min(height, rows[-1] + 1 + pad),
            max(0, cols[0] - pad), min(width, cols[-1] + 1 + pad))


def _signed_distance(coverage: np.ndarray) -> np.ndarray:
    """(H, W) float32 signed distance to the 0.5-coverage contour of an (H, W) coverage."""
    height, width = coverage.shape
    fine = cv2.resize(coverage, (width * SUBPIXEL, height * SUBPIXEL), interpolation=cv2.INTER_LINEAR)
    inside = (fine > 0.5).astype(np.uint8)
    # Distance from each pixel to the nearest pixel of the other side; the contour lies half
    # a (fine) pixel before it.
    outside_distance = cv2.distanceTransform(1 - inside, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    inside_distance = cv2.distanceTransform(inside, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    signed = np.where(inside > 0, 0.5 - inside_distance, outside_distance - 0.5) / SUBPIXEL
    # INTER_AREA averages each SUBPIXEL^2 block, whose centre is the coarse pixel's centre.
    return cv2.resize(signed.astype(np.float32), (width, height), interpolation=cv2.INTER_AREA)


@dataclass(frozen=True)
class SilhouetteProfile:
    """The mean map value against the signed distance to the outline, over all views.

    Attributes:
        distances: (B,) bin centres in px (> 0 outside).
        values: (B,) mean map value per bin (0 where a bin is empty).
        offset_px: where the profile peaks (parabola through the top bin and its neighbours);
            > 0: the maps draw the outline outside the object.
        pixels: how many pixels were averaged.
    """

    distances: np.ndarray
    values: np.ndarray
    offset_px: float
    pixels: int

    def to_dict(self) -> dict:
        return {"offset_px": round(self.offset_px, 4), "pixels": self.pixels,
                "distances": [round(float(d), 3) for d in self.distances],
                "values": [round(float(v), 5) for v in self.values]}


def measure_silhouette_profile(edge_maps: Sequence[np.ndarray], outlines: Sequence[Outline]
                               ) -> SilhouetteProfile:
    """Mean profile of (H, W) maps across their views' outlines, and its peak.

    Raises:
        ValueError when no pixel lies near an outline (no object in any view).
    """
    edges = np.arange(-PROFILE_RANGE_PX, PROFILE_RANGE_PX + PROFILE_BIN_PX / 2, PROFILE_BIN_PX)
    sums = np.zeros(len(edges) - 1)
    counts = np.zeros(len(edges) - 1)
    for edge_map, outline in zip(edge_maps, outlines, strict=True):
        near = np.abs(outline.distance) < PROFILE_RANGE_PX
        bins = np.clip(np.digitize(outline.distance[near], edges) - 1, 0, len(sums) - 1)
        sums += np.bincount(bins, weights=edge_map[near], minlength=len(sums))
        counts += np.bincount(bins, minlength=len(sums))
    if counts.sum() == 0:
        raise ValueError("no pixel near an object outline: the masks are empty or full")
    values = np.where(counts > 0, sums / np.maximum(counts, 1), 0.0)
    centres = (edges[:-1] + edges[1:]) / 2
    top = int(np.clip(np.argmax(values), 1, len(values) - 2))
    peak = float(centres[top] + parabola_vertex(*values[top - 1:top + 2]) * PROFILE_BIN_PX)
    return SilhouetteProfile(centres, values, peak, int(counts.sum()))


def distances_read(reach_px: float) -> float:
    """How far from the outline (px) the profile's measurement and a pull of `reach_px` read
    an Outline's distance (`Outline.from_coverage`'s `within`)."""
    return max(PROFILE_RANGE_PX, 2.0 * reach_px)


@dataclass(frozen=True)
class OutlinePull:
    """Moves a view's maps inwards by `offset_px` along the outline's normal near the outline.

    out(x) = map(x + offset * n(x) * w(x)), with w = 1 within `reach_px` of the outline, fading
    linearly to 0 at twice that: a band drawn at distance `offset` comes to lie on the outline,
    while edges deep inside the object do not move. The sampling field is built once per view
    and applied to both the view's map and its mask of edge pixels.

    map_x, map_y: (H, W) float32 coordinates where each output pixel samples its input.
    """

    map_x: np.ndarray
    map_y: np.ndarray

    @classmethod
    def towards(cls, outline: Outline, offset_px: float, reach_px: float) -> OutlinePull:
        """The pull onto `outline` (at the map's resolution) of bands drawn `offset_px` outside
        it (< 0: inside), applied in full within `reach_px` of it."""
        if outline.within is not None and distances_read(reach_px) > outline.within:
            raise ValueError(f"a pull of reach {reach_px} px reads the outline {distances_read(reach_px)} px "
                             f"away, but it was made within {outline.within} px")
        height, width = outline.distance.shape
        weight = np.clip(2.0 - np.abs(outline.distance) / reach_px, 0.0, 1.0) * offset_px
        xs, ys = np.meshgrid(np.arange(width, dtype=np.float32), np.arange(height, dtype=np.float32))
        return cls((xs + outline.normal[..., 0] * weight).astype(np.float32),
                   (ys + outline.normal[..., 1] * weight).astype(np.float32))

    def apply(self, edge_map: np.ndarray, nearest: bool = False) -> np.ndarray:
        """The (H, W) float32 pulled map, or a bool mask with `nearest`, which samples the nearest
        pixel instead of interpolating: masks of edge pixels hold thin lines that would otherwise
        fall below the edge threshold (a 1 px line moved by 0.3 px loses a third of its peak)."""
        pulled = cv2.remap(np.asarray(edge_map, np.float32), self.map_x, self.map_y,
                           interpolation=cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
        return pulled > 0.5 if edge_map.dtype == bool else pulled
