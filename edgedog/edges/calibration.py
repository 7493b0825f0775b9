"""A detector's calibration: where it draws its edges relative to the true ones, as a record.

Learned detectors are biased: PiDiNet's maps of the ABC objects peak 0.5-1 px up and to the left
of the projected ground-truth curves, and on silhouettes their bands lie mostly outside the
object. `edgedog calibrate-detector` measures the bias (`edgedog.bench.calibrate`) and keeps one
record per detector and weights here (`save_calibration`, `load_calibration`); training's
`maps.correction = 'calibrated'` reads it and `edgedog.edges.correct` applies it.

Sign convention, used everywhere: an *offset* is where the map's ridge lies relative to the
projected ground truth, in pixels (x right, y down). The 2D offset (dx, dy) is the shift d that
maximises the mean map value sampled at `gt + d`; an offset along a normal n is the position s
of the peak of the mean profile `map(gt + s n)`. The *correction* is minus the offset: moving
the map by it puts the ridge on the ground truth.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from edgedog.edges.detector import EdgeDetector
from edgedog.errors import InputError
from edgedog.files import atomic_write_json, default_cache, read_json

PROFILE_STEP = 0.25
PROFILE_OFFSETS = np.arange(-24, 25) * PROFILE_STEP
"""(49,) px along the normal at which across-edge profiles are sampled: -6 .. 6."""
FWHM_PER_SIGMA = 2.0 * np.sqrt(2.0 * np.log(2.0))
CALIBRATION_FOLDER = "calibration"


def parabola_vertex(left: float, centre: float, right: float) -> float:
    """Where the parabola through (-1, left), (0, centre), (1, right) peaks, in [-0.5, 0.5]."""
    curvature = left - 2 * centre + right
    return float(np.clip(0.5 * (left - right) / curvature, -0.5, 0.5)) if curvature < 0 else 0.0


@dataclass(frozen=True)
class EdgeProfile:
    """The mean across-edge profile of a set of curve points: the map sampled at
    `point + s * normal` for s in PROFILE_OFFSETS and averaged over the points.

    Attributes:
        values: (49,) the mean map value at each of PROFILE_OFFSETS.
        peak_px: where it peaks (parabolic fit), px along the normal: the offset.
        width_px: its width as the standard deviation of a Gaussian with the same full width
            at half maximum (above the profile's minimum), px.
        asymmetry: (right - left) / (right + left) of the half widths at half maximum on the
            +normal (right) and -normal (left) sides of the peak, in [-1, 1]; > 0 when the band
            reaches further along +normal.
    """

    values: tuple[float, ...]
    peak_px: float
    width_px: float
    asymmetry: float

    @classmethod
    def from_values(cls, values: np.ndarray) -> EdgeProfile:
        """Peak, width and asymmetry of a (49,) profile sampled at PROFILE_OFFSETS."""
        stored = tuple(round(float(v), 5) for v in values)
        top = int(np.argmax(values))
        if values[top] <= values.min():  # flat: no band at all
            return cls(stored, float(PROFILE_OFFSETS[top]), 0.0, 0.0)
        peak = PROFILE_OFFSETS[top]
        if 0 < top < len(values) - 1:
            peak += PROFILE_STEP * parabola_vertex(*values[top - 1:top + 2])
        left, right = (_half_crossing(values, top, direction) for direction in (-1, 1))
        asymmetry = ((right - peak) - (peak - left)) / (right - left)
        return cls(stored, float(peak), float((right - left) / FWHM_PER_SIGMA), float(asymmetry))

    @classmethod
    def from_dict(cls, record: dict) -> EdgeProfile:
        return cls(tuple(record["values"]), record["peak_px"], record["width_px"], record["asymmetry"])


def _half_crossing(values: np.ndarray, top: int, direction: int) -> float:
    """Where `values` (sampled at PROFILE_OFFSETS) first falls to half its height above its
    minimum, walking from index `top` in `direction` (+1 or -1); linear interpolation, or the
    window's end when it never does."""
    half = (values[top] + values.min()) / 2
    index = top
    while 0 <= index + direction < len(values) and values[index + direction] > half:
        index += direction
    if not 0 <= index + direction < len(values):
        return float(PROFILE_OFFSETS[index])
    above, below = values[index], values[index + direction]
    return float(PROFILE_OFFSETS[index] + direction * PROFILE_STEP * (above - half) / (above - below))


@dataclass(frozen=True)
class OrientationOffset:
    """The offset of the curve points whose normal lies in one orientation bin.

    Attributes:
        angle_deg: the bin's centre: the direction of its normal n = (cos, sin) in the image
            (x right, y down), in [0, 180); 0 = vertical edges, 90 = horizontal edges.
        offset_px: the ridge's position along n (peak of the bin's mean profile).
        points: how many points the bin holds.
    """

    angle_deg: float
    offset_px: float
    points: int


@dataclass(frozen=True)
class OffsetMeasurement:
    """What `edgedog.bench.calibrate.measure_offset` finds (sign convention: see the module's docstring).

    Attributes:
        offset_px: (dx, dy) the map's ridge relative to the projected ground truth.
        orientations: the offset along the normal, per orientation bin.
        profile: the band's own across-edge profile: each orientation bin's mean profile (along
            the bin's direction) moved to peak at 0, averaged. Its width is the band's width.
        silhouette: the mean profile of the silhouette points along their outward normals (its
            peak is how far outside the object the band peaks), or None without any.
        points: curve points measured.
        silhouette_points: how many of them are silhouette points.
    """

    offset_px: tuple[float, float]
    orientations: tuple[OrientationOffset, ...]
    profile: EdgeProfile
    silhouette: EdgeProfile | None
    points: int
    silhouette_points: int

    @property
    def correction(self) -> tuple[float, float]:
        """(dx, dy) to move the map by (`correct.shift_edge_map`) to put its ridge on the truth."""
        return -self.offset_px[0], -self.offset_px[1]

    @property
    def silhouette_offset_px(self) -> float | None:
        """How far outside the object the band peaks on silhouettes (< 0: inside)."""
        return None if self.silhouette is None else self.silhouette.peak_px

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, record: dict) -> OffsetMeasurement:
        silhouette = record["silhouette"]
        return cls(tuple(record["offset_px"]), tuple(OrientationOffset(**o) for o in record["orientations"]),
                   EdgeProfile.from_dict(record["profile"]),
                   None if silhouette is None else EdgeProfile.from_dict(silhouette),
                   record["points"], record["silhouette_points"])


@dataclass(frozen=True)
class DetectorCalibration:
    """A detector's measured bias, from built-in parts rendered with exact ground truth.

    Attributes:
        detector: its name.
        fingerprint: its fingerprint (weights hash and settings): the record's key with the name.
        overall: the measurement over every size.
        per_size: image size (px) -> the measurement at that size.
        shapes, views, seed: the parts (`make_part` names and seed) and orbit views per size.
        date: when it was measured (ISO 8601, UTC).
    """

    detector: str
    fingerprint: str
    overall: OffsetMeasurement
    per_size: dict[int, OffsetMeasurement]
    shapes: tuple[str, ...]
    views: int
    seed: int
    date: str

    @property
    def offset_px(self) -> tuple[float, float]:
        return self.overall.offset_px

    @property
    def correction(self) -> tuple[float, float]:
        return self.overall.correction

    @property
    def silhouette_offset_px(self) -> float | None:
        return self.overall.silhouette_offset_px

    @property
    def profile_width_px(self) -> float:
        return self.overall.profile.width_px

    @property
    def asymmetry(self) -> float | None:
        """Outward asymmetry of the silhouette profile (> 0: the band reaches further outside)."""
        return None if self.overall.silhouette is None else self.overall.silhouette.asymmetry

    @property
    def points(self) -> int:
        return self.overall.points

    def to_dict(self) -> dict:
        record = dataclasses.asdict(self)
        record["per_size"] = {str(size): m.to_dict() for size, m in self.per_size.items()}
        return record

    @classmethod
    def from_dict(cls, record: dict) -> DetectorCalibration:
        return cls(record["detector"], record["fingerprint"], OffsetMeasurement.from_dict(record["overall"]),
                   {int(size): OffsetMeasurement.from_dict(m) for size, m in record["per_size"].items()},
                   tuple(record["shapes"]), record["views"], record["seed"], record["date"])


def calibration_path(detector: str, fingerprint: str) -> Path:
    """`<user cache>/calibration/<detector>-<fingerprint>.json`, unsafe characters replaced."""
    name = re.sub(r"[^A-Za-z0-9_.-]", "-", f"{detector}-{fingerprint}")
    return default_cache() / CALIBRATION_FOLDER / f"{name}.json"


def save_calibration(calibration: DetectorCalibration) -> Path:
    """Write the record atomically; returns its path."""
    path = calibration_path(calibration.detector, calibration.fingerprint)
    return atomic_write_json(path, calibration.to_dict())


def load_calibration(detector: EdgeDetector) -> DetectorCalibration | None:
    """The record of this detector with these weights and settings, or None when there is none."""
    path = calibration_path(detector.name, detector.fingerprint)
    if not path.is_file():
        return None
    record = read_json(path)
    try:
        calibration = DetectorCalibration.from_dict(record)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(path, f"not a detector calibration record ({type(exc).__name__}: {exc})") from None
    same = (calibration.detector, calibration.fingerprint) == (detector.name, detector.fingerprint)
    return calibration if same else None
