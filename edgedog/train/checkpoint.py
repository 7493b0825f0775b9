"""checkpoint.pt: what a run needs to continue exactly, stored as data that loading cannot execute.

Files in run folders come from other people. A checkpoint is written with `torch.save` of plain
data only (tensors, numbers, strings, lists, tuples, dicts; numpy arrays are stored as tensors)
and read back with `torch.load(weights_only=True)`, whose unpickler builds nothing else: a
crafted file can fail to load, never run code. The payload is stamped with a format name and
version; checkpoints written before the version existed (a full pickle) are refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch

from edgedog.errors import InputError
from edgedog.files import atomic_write
from edgedog.primitives import RAW, SCHEMA

CHECKPOINT = "checkpoint.pt"
FORMAT = "edgedog-checkpoint"
VERSION = 2
REQUIRED = ("config", "step_index", "model", "optimizers", "absgrad", "pruned_positions", "fisher",
            "generator", "history", "events", "seconds", "bad_gradients", "init_report", "initial_count",
            "detector", "lower")
"""The entries every checkpoint of this version holds (see `Trainer.save_checkpoint`)."""


def to_storable(value: Any) -> Any:
    """`value` with numpy arrays as tensors and numpy scalars as Python numbers, recursively
    through dicts, lists and tuples (what the weights-only unpickler can rebuild)."""
    if isinstance(value, np.ndarray):
        return torch.from_numpy(np.ascontiguousarray(value).copy())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {key: to_storable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(to_storable(item) for item in value)
    return value


def to_numpy(value: Any) -> Any:
    """The inverse of `to_storable` for a part stored from numpy: tensors back to arrays."""
    if isinstance(value, torch.Tensor):
        return value.numpy()
    if isinstance(value, dict):
        return {key: to_numpy(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(to_numpy(item) for item in value)
    return value


def write_checkpoint(path: Path, payload: dict) -> Path:
    """Stamp `payload` and write it atomically (a crash keeps the previous checkpoint)."""
    stamped = {"format": FORMAT, "version": VERSION, **to_storable(payload)}
    return atomic_write(path, lambda file: torch.save(stamped, file))


def read_checkpoint(path: Path) -> dict:
    """The payload of a checkpoint; one InputError naming the file for anything else (a pickle
    that would build objects, an older format, a truncated or foreign file)."""
    path = Path(path)
    if path.is_dir():
        raise InputError(path, "is a folder, not a checkpoint")
    if not path.is_file():
        raise InputError(path, "no checkpoint (is this a run folder written by `edgedog train`?)")
    try:
        saved = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for a bad file (unpickling, zip, EOF, runtime)
        if "weights_only" in str(exc) or "Unsupported global" in str(exc):
            raise InputError(path, "holds Python objects that loading would have to build (a checkpoint "
                                   "of an older edgedog, or a crafted file); not loaded. Retrain the run"
                             ) from None
        first_line = (str(exc).strip().splitlines() or [type(exc).__name__])[0][:200]
        raise InputError(path, f"not a readable checkpoint ({first_line})") from None
    if not isinstance(saved, dict) or saved.get("format") != FORMAT:
        raise InputError(path, "not an edgedog checkpoint")
    if saved.get("version") != VERSION:
        raise InputError(path, f"checkpoint format version {saved.get('version')!r}; this edgedog reads "
                               f"version {VERSION}")
    missing = [key for key in REQUIRED if key not in saved]
    if missing:
        raise InputError(path, f"incomplete checkpoint: no {', '.join(missing)}")
    return saved


def model_arrays(saved: dict, key: str, path: Path, with_layers: bool = False) -> dict[str, np.ndarray]:
    """`saved[key]`, a model's parameter groups (`edgedog.primitives.RAW`; and, `with_layers`, each
    primitive's layer) as numpy arrays after checking that they are one model: N rows each, the
    schema's widths, finite."""
    value = saved[key]
    names = (*RAW, "layers") if with_layers else RAW
    if not isinstance(value, dict) or not all(isinstance(value.get(name), torch.Tensor) for name in names):
        raise InputError(path, f"malformed checkpoint: '{key}' must hold the tensors {', '.join(names)}")
    arrays = {name: value[name].numpy() for name in names}
    count = len(arrays["means"])
    shapes = {p.raw: p.shape(count) for p in SCHEMA} | {"layers": (count,)}
    for name, array in arrays.items():
        if array.shape != shapes[name]:
            raise InputError(path, f"malformed checkpoint: '{key}.{name}' has shape {array.shape}, "
                                   f"expected {shapes[name]}")
        if name != "layers" and (array.dtype != np.float32 or not np.isfinite(array).all()):
            raise InputError(path, f"malformed checkpoint: '{key}.{name}' must be finite float32")
    return arrays
