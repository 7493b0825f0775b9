"""The multi-granularity layers of a model, for the layer list of the 3D view.

Training has one layer today, "L0", holding every primitive; layered training will give each
primitive its layer. The view hides a layer by leaving its primitives out of the upload.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


def layer_members(snapshot) -> dict[str, np.ndarray]:
    """Layer name -> (n,) indices of the snapshot's primitives in it."""
    return {"L0": np.arange(len(snapshot.means))}


def visible_members(snapshot, shown: Mapping[str, bool]) -> np.ndarray:
    """(n,) sorted indices of the primitives in the shown layers (a layer not listed is shown)."""
    members = [idx for name, idx in layer_members(snapshot).items() if shown.get(name, True)]
    return np.unique(np.concatenate(members)) if members else np.zeros(0, np.int64)
