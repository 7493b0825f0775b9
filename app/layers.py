"""The multi-granularity layers of a model, for the layer lists of the 3D view and the 2D render.

A snapshot's `layers` gives each primitive's layer index (None: a single-layer run, all "L0").
A view hides a layer by leaving its primitives out of what it draws.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from edgedog.train.layers import layer_name


def layer_members(snapshot) -> dict[str, np.ndarray]:
    """Layer name -> (n,) indices of the snapshot's primitives in it, bottom layer first."""
    if snapshot.layers is None:
        return {layer_name(0): np.arange(len(snapshot.means))}
    return {layer_name(int(i)): np.flatnonzero(snapshot.layers == i) for i in np.unique(snapshot.layers)}


def visible_members(snapshot, shown: Mapping[str, bool]) -> np.ndarray:
    """(n,) sorted indices of the primitives in the shown layers (a layer not listed is shown)."""
    members = [idx for name, idx in layer_members(snapshot).items() if shown.get(name, True)]
    return np.unique(np.concatenate(members)) if members else np.zeros(0, np.int64)


def visible_subset(snapshot, shown: Mapping[str, bool]):
    """A copy of the snapshot with the primitives of the shown layers only."""
    members = visible_members(snapshot, shown)

    def rows(array):  # every per-primitive array; the optional ones (layers, b) may be None
        return None if array is None else array[members]

    return dataclasses.replace(snapshot, means=rows(snapshot.means), scales=rows(snapshot.scales),
                               quats=rows(snapshot.quats), opacity=rows(snapshot.opacity),
                               k_raw=rows(snapshot.k_raw), layers=rows(snapshot.layers),
                               opacity_dirs=rows(snapshot.opacity_dirs))


def selection(snapshot, shown: Mapping[str, bool]) -> str:
    """The shown layers as `edgedog export --layers` names a selection ('L1', 'L0+L1'), or ''
    when every layer is shown."""
    layers = layer_members(snapshot)
    names = [name for name in layers if shown.get(name, True)]
    return "" if len(names) == len(layers) else "+".join(names)


def finest(snapshot, shown: Mapping[str, bool]) -> int | None:
    """The index of the highest layer shown (None when none is)."""
    names = [name for name in layer_members(snapshot) if shown.get(name, True)]
    return int(names[-1][1:]) if names else None


def list_new_layers(shown: dict[str, bool], snapshot) -> None:
    """Add the snapshot's layers missing from a layer list `shown` (name -> shown), shown."""
    for name in layer_members(snapshot):
        shown.setdefault(name, True)
