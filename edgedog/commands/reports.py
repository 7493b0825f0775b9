"""The reports `edgedog train`, `extract` and `demo` print: counts and scores of a run's curves."""

from __future__ import annotations


def print_report(report: dict) -> None:
    """The counts, then a table of the points' and curves' scores when there is ground truth."""
    for name, count in report["counts"].items():
        print(f"{name.replace('_', ' '):<18} {count}")
    if "metrics" in report:
        print(f"vs {report['ground_truth']}")
        print(f"{'':<8} {'Acc (mm)':>8} {'Comp (mm)':>9} {'F5':>7} {'F10':>7} {'F20':>7}")
        for name, m in report["metrics"].items():
            print(f"{name:<8} {m['acc_mm']:8.2f} {m['comp_mm']:9.2f} {m['fscore_5mm']:7.2f} "
                  f"{m['fscore_10mm']:7.2f} {m['fscore_20mm']:7.2f}")


def print_layers_report(report: dict) -> None:
    """One row per selection: primitives, curves, and the curves' scores when there is ground truth."""
    print(f"{'layers':<12} {'primitives':>10} {'curves':>6} {'Acc':>6} {'Comp':>6} {'P10':>6} {'R10':>6} "
          f"{'F10':>6} {'F20':>6}")
    for name, selection in report["selections"].items():
        counts = selection["counts"]
        row = f"{name:<12} {selection['primitives']:>10} {counts['lines'] + counts['beziers']:>6}"
        curves = selection.get("metrics", {}).get("curves")
        if curves:
            row += (f" {curves['acc_mm']:6.2f} {curves['comp_mm']:6.2f} {curves['precision_10mm']:6.1f} "
                    f"{curves['recall_10mm']:6.1f} {curves['fscore_10mm']:6.1f} {curves['fscore_20mm']:6.1f}")
        print(row)
