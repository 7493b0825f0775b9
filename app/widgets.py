"""The studio's widgets: imgui's, each with the tooltip that says what it does and when it
applies, and with its rectangle noted so that the scripted driver can click it (through imgui's
own input queue, as a mouse would).
"""

from __future__ import annotations

from collections.abc import Sequence

from imgui_bundle import imgui

RECTS: dict[str, tuple[float, float, float, float]] = {}
"""Label -> (x0, y0, x1, y1) in screen points of the widgets drawn by the last frame."""
CUT: set[str] = set()
"""Labels of the widgets the last frame drew only partly or not at all in their panel (beyond its
bottom: reached only by scrolling)."""


def note(label: str, tip: str) -> None:
    """Note the last item's rectangle under `label` and give it the tooltip `tip` (none when empty)."""
    low, high = imgui.get_item_rect_min(), imgui.get_item_rect_max()
    RECTS[label] = (low.x, low.y, high.x, high.y)
    top, bottom = imgui.get_window_pos().y, imgui.get_window_pos().y + imgui.get_window_size().y
    if low.y < top or high.y > bottom:
        CUT.add(label)
    if tip:
        imgui.set_item_tooltip(tip)


def button(label: str, tip: str, small: bool = False) -> bool:
    clicked = imgui.small_button(label) if small else imgui.button(label)
    note(label, tip)
    return clicked


def checkbox(label: str, value: bool, tip: str) -> bool:
    value = imgui.checkbox(label, value)[1]
    note(label, tip)
    return value


def combo(label: str, value: str, items: Sequence[str], tip: str, names: Sequence[str] | None = None) -> str:
    """A combo box over `items` (shown as `names`, default the items) that returns the chosen item."""
    index = imgui.combo(label, list(items).index(value), list(names or items))[1]
    note(label, tip)
    return items[index]


def slider_float(label: str, value: float, low: float, high: float, tip: str, fmt: str = "%.2f") -> float:
    value = imgui.slider_float(label, value, low, high, fmt)[1]
    note(label, tip)
    return value


def slider_int(label: str, value: int, low: int, high: int, tip: str) -> int:
    value = imgui.slider_int(label, value, low, high)[1]
    note(label, tip)
    return value


def input_int(label: str, value: int, tip: str, step: int = 1, fast: int = 10) -> int:
    value = imgui.input_int(label, value, step, fast)[1]
    note(label, tip)
    return value


def input_float2(label: str, value: Sequence[float], tip: str, fmt: str = "%.2f") -> tuple[float, float]:
    value = imgui.input_float2(label, list(value), fmt)[1]
    note(label, tip)
    return tuple(value)


def center(label: str) -> tuple[float, float]:
    """The centre of widget `label` as last drawn (KeyError when it was not)."""
    x0, y0, x1, y1 = RECTS[label]
    return (x0 + x1) / 2, (y0 + y1) / 2
