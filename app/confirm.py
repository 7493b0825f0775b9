"""A question asked before something that would stop a training run (quit, Restart, opening
another folder): a small modal window, Enter (or its button) confirms, Esc (or Cancel) drops it.

The modal owns the keyboard while it is open: its keys are read here, and the studio's shortcuts
wait (`shortcuts.handle_keys`).
"""

from __future__ import annotations

from edgedog.app import widgets
from edgedog.app.state import Request
from imgui_bundle import imgui

TITLE = "Confirm##confirm"
YES_KEYS = (imgui.Key.enter, imgui.Key.keypad_enter)


class Confirm:
    """One question: `draw()` each frame returns True once confirmed, False once cancelled, None
    meanwhile; `request` is what a yes asks for."""

    def __init__(self, question: str, yes: str, request: Request):
        self.question, self.yes, self.request = question, yes, request
        self._asked_at = imgui.get_frame_count()
        """The key that asked (q, Esc) is still down in this frame: it must not answer too."""

    def draw(self) -> bool | None:
        if not imgui.is_popup_open(TITLE):
            imgui.open_popup(TITLE)
        viewport = imgui.get_main_viewport()
        imgui.set_next_window_pos(viewport.get_center(), imgui.Cond_.always, imgui.ImVec2(0.5, 0.5))
        answer = None
        flags = imgui.WindowFlags_.always_auto_resize | imgui.WindowFlags_.no_move
        if imgui.begin_popup_modal(TITLE, None, flags)[0]:
            imgui.text(self.question)
            if widgets.button(f"{self.yes} (Enter)", ""):
                answer = True
            imgui.same_line()
            if widgets.button("Cancel (Esc)", "keep things as they are"):
                answer = False
            if answer is None and imgui.get_frame_count() > self._asked_at:
                if any(imgui.is_key_pressed(key, False) for key in YES_KEYS):
                    answer = True
                elif imgui.is_key_pressed(imgui.Key.escape, False):
                    answer = False
            if answer is not None:
                imgui.close_current_popup()
            imgui.end_popup()
        return answer
