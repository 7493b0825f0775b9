"""Open...: an in-window folder browser, so that opening needs no external program (the system
dialogs of portable-file-dialogs need zenity or kdialog on Linux, and say nothing without them).

It lists the sub-folders of one folder, each marked when it is a scene, a run or a folder of
photos (which Open offers to take through structure from motion); a double click (or Enter on a
typed path) goes into a folder, "Open" opens the one shown.
"""

from __future__ import annotations

import os
from pathlib import Path

from edgedog.app import widgets
from edgedog.app.photos import has_photos
from imgui_bundle import imgui

from edgedog.scenes import FORMATS
from edgedog.train.lifecycle import record_kind

TITLE = "Open a scene, run or photo folder"
PHOTOS = "photos"
"""The kind of a folder that holds images and is neither a scene nor a run."""
MAX_ENTRIES = 2000
"""Sub-folders listed at most (a huge folder is cut short, with a note)."""


def folder_kind(path: Path) -> str:
    """'run', 'layered run', a scene format's name, PHOTOS, or '' for any other folder."""
    kind = record_kind(path)
    if kind:
        return kind
    for name, test, _ in FORMATS:
        try:
            if test(path):
                return f"{name} scene"
        except OSError:  # an unreadable folder is listed as a plain one
            return ""
    return PHOTOS if has_photos(path) else ""


def sub_folders(path: Path) -> tuple[list[str], str]:
    """Sorted names of the visible sub-folders of `path` (at most MAX_ENTRIES), and a note: why
    none could be read, or that the list was cut short."""
    try:
        with os.scandir(path) as entries:
            names = sorted(entry.name for entry in entries
                           if not entry.name.startswith(".") and entry.is_dir())
    except OSError as error:
        return [], f"cannot read this folder ({error.strerror})"
    if len(names) > MAX_ENTRIES:
        return names[:MAX_ENTRIES], f"showing the first {MAX_ENTRIES} of {len(names)} folders"
    return names, ""


class FolderDialog:
    """The browser's state. `draw()` each frame returns the folder chosen once (None meanwhile);
    `open` turns False when it is closed either way."""

    def __init__(self, opened: Path):
        """Shows the folder holding `opened` (the scene or run open now), with it selected."""
        opened = Path(opened).expanduser().resolve()
        self.open, self._appearing, self._focus_path = True, True, True
        self.go(opened.parent)
        self.selected = opened.name if any(name == opened.name for name, _ in self.entries) else None

    def go(self, path: Path) -> None:
        """Show the folder `path` (an unreadable one shows why)."""
        self.path, self.typed, self.selected = path, str(path), None
        names, self.note = sub_folders(path)
        self.entries = [(name, folder_kind(path / name)) for name in names]

    def draw(self) -> Path | None:
        chosen = None
        viewport = imgui.get_main_viewport()
        imgui.set_next_window_pos(viewport.get_center(), imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
        imgui.set_next_window_size(imgui.ImVec2(viewport.size.x * 0.6, viewport.size.y * 0.6),
                                   imgui.Cond_.appearing)
        if self._appearing:
            imgui.set_next_window_focus()
            self._appearing = False
        expanded, self.open = imgui.begin(TITLE, self.open, imgui.WindowFlags_.no_collapse)
        if expanded:
            chosen = self._contents()
        imgui.end()
        if chosen is not None:
            self.open = False
        return chosen

    def _contents(self) -> Path | None:
        if self._focus_path:  # a path can be typed at once
            imgui.set_keyboard_focus_here()
            self._focus_path = False
        entered, self.typed = imgui.input_text("folder", self.typed, imgui.InputTextFlags_.enter_returns_true)
        imgui.set_item_tooltip("type a path and press Enter to go there")
        if imgui.is_item_deactivated() and imgui.is_key_pressed(imgui.Key.escape, False):
            self.open = False  # Esc closes the browser, typing or not (the shortcuts skip text input)
        if entered:
            typed = Path(self.typed).expanduser()
            if typed.is_dir():
                self.go(typed.resolve())
            else:
                self.note = f"{typed}: no such folder"
        if widgets.button("Up", "the parent folder") and self.path.parent != self.path:
            self.go(self.path.parent)
        imgui.same_line()
        target = self.path / self.selected if self.selected else self.path
        chosen = target if widgets.button("Open", f"open {target}") else None
        imgui.same_line()
        if widgets.button("Cancel##open", "close this browser without opening anything"):
            self.open = False
        kind = folder_kind(self.path)
        imgui.text_disabled(f"{self.path}  {('(' + kind + ')') if kind else ''}")
        if self.note:
            imgui.text_disabled(self.note)
        if imgui.begin_child("##folders", imgui.ImVec2(0, 0), imgui.ChildFlags_.borders):
            for name, kind in self.entries:
                label = f"{name}/   {kind}" if kind else f"{name}/"
                clicked = imgui.selectable(label, name == self.selected,
                                           imgui.SelectableFlags_.allow_double_click)[0]
                if clicked:
                    self.selected = name
                    if imgui.is_mouse_double_clicked(imgui.MouseButton_.left):
                        self.go(self.path / name)
                        break
        imgui.end_child()
        return chosen
