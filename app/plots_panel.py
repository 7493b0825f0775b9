"""The plots panel (implot): loss, primitive count and, with ground truth, F-scores, over time.
Stacked when each gets a readable height, else one at a time in tabs (a short window)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from edgedog.app import layout
from imgui_bundle import imgui, implot

AUTO_FIT = implot.AxisFlags_.auto_fit
MARKERS = implot.Spec(marker=implot.Marker_.circle)
"""F-scores come once per extraction: markers show the sparse points."""
FIT_PADDING = imgui.ImVec2(0.05, 0.12)
"""Room around the fitted data (shares of each axis): a marker on the edge shows whole."""
MIN_PLOT_HEIGHT = 130
"""The least height of a stacked plot (unscaled points): its title, ticks, axis label and legend
leave it a readable area."""

Series = dict[str, tuple[np.ndarray, np.ndarray]]


def _plot(title: str, height: float, series: Series, spec: implot.Spec | None = None) -> None:
    """One plot of named (time, value) series, both axes fitted to the data; the legend, when
    there is one, sits outside the plot, above it."""
    flags = implot.Flags_.no_menus | (0 if len(series) > 1 else implot.Flags_.no_legend)
    implot.push_style_var(implot.StyleVar_.fit_padding, FIT_PADDING)
    if implot.begin_plot(title, imgui.ImVec2(-1, height), flags):
        implot.setup_axes("time (s)", "", AUTO_FIT, AUTO_FIT)
        implot.setup_legend(implot.Location_.north,
                            implot.LegendFlags_.outside | implot.LegendFlags_.horizontal)
        for label, (xs, ys) in series.items():
            xs, ys = (np.ascontiguousarray(values, np.float64) for values in (xs, ys))  # implot wants these
            implot.plot_line(label, xs, ys, spec)
        implot.end_plot()
    implot.pop_style_var()


def _plots(studio) -> list[tuple[str, Callable[[float], None]]]:
    """(tab name, draw at a height) of each plot."""
    worker, run = studio.worker, studio.run_token
    rows = np.zeros((0, 3)) if worker is None else worker.series()
    plots = [("loss", lambda height: _plot(f"loss##{run}", height, {"loss": (rows[:, 0], rows[:, 1])})),
             ("primitives", lambda height: _plot(f"primitives##{run}", height,
                                                 {"primitives": (rows[:, 0], rows[:, 2])}))]
    if studio.session.ground_truth is None:
        return [*plots, ("F-score", lambda _height: imgui.text_disabled("no ground truth: no F-scores"))]
    times = np.array([elapsed for elapsed, _ in studio.fscores], np.float64)
    thresholds = studio.fscores[0][1] if studio.fscores else {}
    series = {f"F {mm} mm": (times, np.array([f[mm] for _, f in studio.fscores], np.float64))
              for mm in thresholds}
    # Named per run: a new run's plot does not keep the last run's axes.
    return [*plots, ("F-score", lambda height: _plot(f"F-score of the curves (%)##{run}", height, series,
                                                     MARKERS))]


def draw(studio, area: layout.Area) -> None:
    if layout.begin("Plots", area):
        plots = _plots(studio)
        spacing = imgui.get_style().item_spacing.y
        height = (imgui.get_content_region_avail().y - (len(plots) - 1) * spacing) / len(plots)
        studio.plots_tabbed = height < MIN_PLOT_HEIGHT * imgui.get_style().font_scale_dpi
        if not studio.plots_tabbed:
            for _, plot in plots:
                plot(height)
        elif imgui.begin_tab_bar("##plots"):
            for name, plot in plots:
                if imgui.begin_tab_item(name)[0]:
                    plot(imgui.get_content_region_avail().y)
                    imgui.end_tab_item()
            imgui.end_tab_bar()
    imgui.end()
