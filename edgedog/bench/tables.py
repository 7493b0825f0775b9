"""Helpers shared by the benchmarks' Markdown tables."""

from __future__ import annotations


def cell(value: float | None, digits: int) -> str:
    """A table cell: the number with `digits` decimals, or an en dash when there is none."""
    return "–" if value is None else f"{value:.{digits}f}"


def spread_cell(mean: float | None, spread: float | None, digits: int, sign: str = "") -> str:
    """A cell of a mean over seeds: `mean ± spread`, the mean alone without a spread, an en dash
    without a mean; `sign` '+' writes the mean's sign always."""
    if mean is None:
        return "–"
    return f"{mean:{sign}.{digits}f}" + ("" if spread is None else f" ± {spread:.{digits}f}")
