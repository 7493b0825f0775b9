"""The primitives' one schema: their parameters raw (as trained) and activated (as shown and
saved), the `primitives.ply` file, and the conversions raw parameters -> activated arrays ->
the oriented edge points that curve extraction reads.

The renderer, training, curve extraction and the studio depend on this module; it depends on
none of them (numpy and plyfile only).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
from plyfile import PlyData, PlyElement

from edgedog.errors import InputError
from edgedog.files import atomic_write


@dataclass(frozen=True)
class Parameter:
    """One parameter group of the primitives.

    Attributes:
        raw: the trained tensor's name (EdgeModel, the rasterizer's Primitives).
        activated: the array's name once activated (Snapshot, `PrimitiveArrays`).
        columns: its vertex properties in primitives.ply, one per component.
        activation: how `raw` becomes `activated` ('identity', 'exp' or 'sigmoid').
        meaning: what the activated values are, with their shape.
    """

    raw: str
    activated: str
    columns: tuple[str, ...]
    activation: str
    meaning: str

    def shape(self, n: int) -> tuple[int, ...]:
        """The shape of `n` primitives' values: (n, components), or (n,) for one component."""
        return (n, len(self.columns)) if len(self.columns) > 1 else (n,)


SCHEMA = (
    Parameter("means", "means", ("x", "y", "z"), "identity", "(N, 3) world positions"),
    Parameter("log_scales", "scales", ("scale_0", "scale_1", "scale_2"), "exp", "(N, 3) axis lengths"),
    Parameter("quats", "quats", ("rot_0", "rot_1", "rot_2", "rot_3"), "identity",
              "(N, 4) rotations (w, x, y, z), any non-zero norm"),
    Parameter("opacity_logits", "opacity", ("opacity",), "sigmoid", "(N,) opacity in (0, 1)"),
    Parameter("k_raw", "k_raw", ("k_0", "k_1"), "identity",
              "(N, 2) DoG shape, activated by the rasterizer (RasterConfig.k_activation)"),
)
"""The parameter groups in primitives.ply's column order."""

RAW = tuple(p.raw for p in SCHEMA)
"""The trained tensors' names, in schema order."""

VIEW_OPACITY = Parameter("opacity_dirs", "opacity_dirs", ("opacity_dir_0", "opacity_dir_1", "opacity_dir_2"),
                         "identity", "(N, 3) direction coefficients b of the view-dependent opacity")
"""Optional parameter group of a run with `model.view_opacity` (edgedog.train.view_opacity): in
the view from direction d (unit, primitive to camera) a primitive's opacity logit is a + b . d.
Where a file has these columns, its `opacity` is each primitive's largest over the training
views (the view-independent opacity that extraction reads), sigmoid(a + max_v b . d_v)."""

UNCERTAINTY = "uncertainty"
"""Optional column: a per-primitive score carried through to edge_points.ply."""
LAYER = "layer"
"""Optional column: the multi-granularity layer of each primitive (edgedog.train.layers)."""

LOGIT_EPS = 1e-6
"""Opacities are clipped to [eps, 1 - eps] before the logit: a float32 sigmoid reaches 1."""



def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 1 / (1 + np.exp(-x))


def _logit(y: np.ndarray) -> np.ndarray:
    y = np.clip(y, LOGIT_EPS, 1 - LOGIT_EPS)
    return np.log(y / (1 - y))


_ACTIVATIONS: dict[str, tuple[Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray]]] = {
    "identity": (lambda x: x, lambda y: y),
    "exp": (np.exp, np.log),
    "sigmoid": (_sigmoid, _logit),
}
"""Activation name -> (forward, inverse), elementwise and dtype-preserving."""


@dataclass(frozen=True)
class PrimitiveArrays:
    """N primitives' activated parameters as numpy arrays (see `SCHEMA` for each one's meaning).

    Attributes:
        means (N, 3), scales (N, 3), quats (N, 4), opacity (N,), k_raw (N, 2).
        layers: (N,) int64 layer index (None: a single-layer run, all in layer 0).
        uncertainty: (N,) optional score (None: the run has none).
        opacity_dirs: (N, 3) b of a view-dependent opacity (`VIEW_OPACITY`; None: the opacity is
            the same from every view).
    """

    means: np.ndarray
    scales: np.ndarray
    quats: np.ndarray
    opacity: np.ndarray
    k_raw: np.ndarray
    layers: np.ndarray | None = None
    uncertainty: np.ndarray | None = None
    opacity_dirs: np.ndarray | None = None

    @classmethod
    def from_raw(cls, raw: Mapping[str, np.ndarray], layers: np.ndarray | None = None) -> PrimitiveArrays:
        """Activate one array per raw parameter (`RAW`, e.g. `EdgeModel.to_numpy()`; other entries
        are not read)."""
        return cls(**{p.activated: _ACTIVATIONS[p.activation][0](raw[p.raw]) for p in SCHEMA}, layers=layers)

    def raw(self) -> dict[str, np.ndarray]:
        """The inverse of `from_raw`: one array per raw parameter (opacities clipped, `LOGIT_EPS`)."""
        return {p.raw: _ACTIVATIONS[p.activation][1](getattr(self, p.activated)) for p in SCHEMA}

    def __len__(self) -> int:
        return len(self.means)

    def subset(self, keep: np.ndarray) -> PrimitiveArrays:
        """The primitives selected by a (N,) bool mask or an index array."""
        return _rows(self, keep)


def _rows(record, keep: np.ndarray):
    """A copy of a dataclass of (N, ...) arrays (or None) with the rows `keep` (mask or indices)."""
    values = {f.name: getattr(record, f.name) for f in fields(record)}
    return type(record)(**{name: None if v is None else v[keep] for name, v in values.items()})


def write_point_columns(path: str | Path, columns: dict[str, np.ndarray]) -> Path:
    """A vertex-only binary PLY, atomically, with one float32 property per column (N,) (x, y, z
    first): primitives.ply, points.ply, edge_points.ply."""
    n = len(next(iter(columns.values())))
    rows = np.empty(n, dtype=[(name, "f4") for name in columns])
    for name, values in columns.items():
        rows[name] = values
    return atomic_write(path, PlyData([PlyElement.describe(rows, "vertex")]).write)


def write_ply(path: str | Path, primitives: PrimitiveArrays) -> Path:
    """primitives.ply: the `SCHEMA` columns first, then `UNCERTAINTY`, `LAYER` and the
    `VIEW_OPACITY` columns when present."""
    columns = {}
    for p in SCHEMA:
        values = getattr(primitives, p.activated).reshape(len(primitives), len(p.columns))
        columns.update({name: values[:, i] for i, name in enumerate(p.columns)})
    for name, values in ((UNCERTAINTY, primitives.uncertainty), (LAYER, primitives.layers)):
        if values is not None:
            columns[name] = values
    if primitives.opacity_dirs is not None:
        columns.update({name: primitives.opacity_dirs[:, i] for i, name in enumerate(VIEW_OPACITY.columns)})
    return write_point_columns(path, columns)


def read_ply(path: str | Path) -> PrimitiveArrays:
    """primitives.ply as written by `edgedog train` (activated values, with the file's dtype).

    Raises InputError naming the file when it is missing, not a PLY, lacks a `SCHEMA` column
    or some of the `VIEW_OPACITY` columns, or holds NaN, infinite values or zero quaternions.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "no such file (is this a run folder written by `edgedog train`?)")
    try:
        vertex = PlyData.read(str(path))["vertex"]
    except Exception as exc:  # plyfile raises many types on malformed files
        raise InputError(path, f"not a readable PLY file with a vertex element ({exc})") from None
    names = set(vertex.data.dtype.names)
    missing = [name for p in SCHEMA for name in p.columns if name not in names]
    if missing:
        raise InputError(path, f"not a primitives PLY: no vertex properties {', '.join(missing)}")
    arrays = {p.activated: np.stack([vertex[name] for name in p.columns], axis=1) for p in SCHEMA}
    arrays["opacity"] = arrays["opacity"][:, 0]
    dir_columns = [name for name in VIEW_OPACITY.columns if name in names]
    if dir_columns and len(dir_columns) < len(VIEW_OPACITY.columns):
        raise InputError(path, f"has {', '.join(dir_columns)} but not all of "
                               f"{', '.join(VIEW_OPACITY.columns)}")
    opacity_dirs = np.stack([vertex[name] for name in dir_columns], axis=1) if dir_columns else None
    geometry = np.hstack([arrays["means"], arrays["scales"], arrays["quats"],
                          np.zeros((len(arrays["means"]), 0)) if opacity_dirs is None else opacity_dirs])
    if not np.all(np.isfinite(geometry)) or np.any(np.all(arrays["quats"] == 0, axis=1)):
        raise InputError(path, "primitives contain NaN, infinite values or zero quaternions")
    layers = np.rint(vertex[LAYER]).astype(np.int64) if LAYER in names else None
    uncertainty = vertex[UNCERTAINTY] if UNCERTAINTY in names else None
    return PrimitiveArrays(**arrays, layers=layers, uncertainty=uncertainty, opacity_dirs=opacity_dirs)


@dataclass
class EdgePrimitives:
    """Primitives as oriented edge points, what curve extraction reads (float64).

    points: (N, 3) centres; directions: (N, 3) unit axes of the largest scale; elongation: (N,)
    largest / middle scale; opacity: (N,) (with a view-dependent opacity, the largest over the
    training views); k: (N, 2) DoG shape; uncertainty: (N,) or None; layers: (N,) int64 layer
    index or None (a single-layer run); opacity_dirs: (N, 3) b of a view-dependent opacity, or
    None.
    """

    points: np.ndarray
    directions: np.ndarray
    elongation: np.ndarray
    opacity: np.ndarray
    k: np.ndarray
    uncertainty: np.ndarray | None = None
    layers: np.ndarray | None = None
    opacity_dirs: np.ndarray | None = None

    @classmethod
    def from_arrays(cls, primitives: PrimitiveArrays) -> EdgePrimitives:
        """The edge points of activated primitives (quaternions must be non-zero)."""
        scales = primitives.scales.astype(np.float64)
        largest = np.argmax(scales, axis=1)
        directions = quaternion_axes(primitives.quats.astype(np.float64))[np.arange(len(scales)), :, largest]
        ordered = np.sort(scales, axis=1)
        elongation = ordered[:, 2] / np.maximum(ordered[:, 1], 1e-12)
        uncertainty = None if primitives.uncertainty is None else primitives.uncertainty.astype(np.float64)
        dirs = None if primitives.opacity_dirs is None else primitives.opacity_dirs.astype(np.float64)
        return cls(primitives.means.astype(np.float64), directions, elongation,
                   primitives.opacity.astype(np.float64), primitives.k_raw.astype(np.float64), uncertainty,
                   primitives.layers, dirs)

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, keep: np.ndarray) -> EdgePrimitives:
        """The primitives selected by a (N,) bool mask or an index array."""
        return _rows(self, keep)

    def in_layers(self, layers: set[int]) -> EdgePrimitives:
        """The primitives of the given layers (a run without layers has everything in layer 0)."""
        own = np.zeros(len(self), np.int64) if self.layers is None else self.layers
        return self.subset(np.isin(own, sorted(layers)))


def quaternion_axes(quats: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of quaternions (N, 4) (w, x, y, z, any non-zero norm)."""
    w, x, y, z = (quats / np.linalg.norm(quats, axis=1, keepdims=True)).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)
