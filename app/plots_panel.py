"""The plots panel (implot): loss, primitive count and, with ground truth, F-scores, over time."""

from __future__ import annotations

import numpy as np
from edgedog.app import layout
from imgui_bundle import imgui, implot

AUTO_FIT = implot.AxisFlags_.auto_fit
MARKERS = implot.Spec(marker=implot.Marker_.circle)
"""F-scores come once per extraction: markers show the sparse points."""


def _plot(title: str, height: float, series: dict[str, tuple[np.ndarray, np.ndarray]],
          spec: implot.Spec | None = None) -> None:
    """One plot of named (time, value) series, both axes fitted to the data; the legend, when
    there is one, sits outside the plot, above it."""
    flags = implot.Flags_.no_menus | (0 if len(series) > 1 else implot.Flags_.no_legend)
    if implot.begin_plot(title, imgui.ImVec2(-1, height), flags):
        implot.setup_axes("time (s)", "", AUTO_FIT, AUTO_FIT)
        implot.setup_legend(implot.Location_.north,
                            implot.LegendFlags_.outside | implot.LegendFlags_.horizontal)
        for label, (xs, ys) in series.items():
            xs, ys = (np.ascontiguousarray(values, np.float64) for values in (xs, ys))  # implot wants these
            implot.plot_line(label, xs, ys, spec)
        implot.end_plot()


def draw(studio, area: layout.Area) -> None:
    if layout.begin("Plots", area):
        worker = studio.worker
        rows = np.zeros((0, 3)) if worker is None else worker.series()
        height = (imgui.get_content_region_avail().y - 2 * imgui.get_style().item_spacing.y) / 3
        _plot(f"loss##{studio.run_token}", height, {"loss": (rows[:, 0], rows[:, 1])})
        _plot(f"primitives##{studio.run_token}", height, {"primitives": (rows[:, 0], rows[:, 2])})
        if studio.session.ground_truth is None:
            imgui.text_disabled("no ground truth: no F-scores")
        else:
            times = np.array([elapsed for elapsed, _ in studio.fscores], np.float64)
            thresholds = studio.fscores[0][1] if studio.fscores else {}
            series = {f"F {mm} mm": (times, np.array([f[mm] for _, f in studio.fscores], np.float64))
                      for mm in thresholds}
            # Named per run: a new run's plot does not keep the last run's axes.
            _plot(f"F-score of the curves (%)##{studio.run_token}", height, series, MARKERS)
    imgui.end()
