"""Helpers shared by the benchmarks' Markdown tables."""

from __future__ import annotations


def cell(value: float | None, digits: int) -> str:
    """A table cell: the number with `digits` decimals, or an en dash when there is none."""
    return "–" if value is None else f"{value:.{digits}f}"
