"""Run folders as format 2 wrote them: the config flat, under the names before the sections."""

from __future__ import annotations

from edgedog.train.config import RENAMED


def flat_config(nested: dict) -> dict:
    """A nested config dict (`to_dict`) as format 2 wrote it: one dict under the old flat names
    (the settings added with the sections left out)."""
    old_names = {dotted: old for old, dotted in RENAMED.items()}
    return {old_names.get(f"{section}.{name}", name): value
            for section, values in nested.items() for name, value in values.items()
            if f"{section}.{name}" != "init.edge_threshold"}
