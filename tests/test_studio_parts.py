"""The studio's parts that need no window: colour maps of empty and constant values, the layer
selections, the folder browser's listing, the scripted keys, and what an aborted start leaves."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import pytest
from edgedog.app.colors import colormap
from edgedog.app.extraction import export_path
from edgedog.app.folder_dialog import folder_kind, sub_folders
from edgedog.app.layers import finest, selection, visible_subset
from edgedog.app.script import press

from edgedog.builtin.scene import write_box_scene
from edgedog.train.config import preset
from edgedog.train.run import discard_scaffold
from edgedog.train.run_folder import LOCK_FILE, RunFolder, write_run
from edgedog.train.trainer import Snapshot


def snapshot_of_layers(layers: list[int]) -> Snapshot:
    n = len(layers)
    return Snapshot(0, 0, 0.0, np.zeros((n, 3)), np.ones((n, 3)), np.tile([1.0, 0, 0, 0], (n, 1)),
                    np.linspace(0.1, 0.9, n), np.zeros((n, 2)), np.zeros((0, 3)), np.array(layers))


def test_no_values_give_no_colours_and_a_constant_one_is_not_black():
    assert colormap(np.zeros(0), 0.0, 1.0, "magma").shape == (0, 3)
    ones = colormap(np.ones((4, 4)), 1.0, 1.0, "magma")  # w(U) = 1 everywhere
    assert (ones == colormap(np.array([1.0]), 0.0, 1.0, "magma")[0]).all()  # the map's top colour
    assert colormap(np.zeros(3), 0.0, 0.0, "gray").max() == 0


def test_the_layers_shown_name_a_selection_and_its_finest_layer():
    snapshot = snapshot_of_layers([0, 0, 1, 2])
    assert selection(snapshot, {}) == "" and finest(snapshot, {}) == 2  # all shown
    assert selection(snapshot, {"L2": False}) == "L0+L1" and finest(snapshot, {"L2": False}) == 1
    hidden = {"L0": False, "L1": False, "L2": False}
    assert finest(snapshot, hidden) is None
    assert len(visible_subset(snapshot, hidden).means) == 0
    assert export_path(Path("run"), 12, "obj", "L0+L1") == Path("run/exports/curves_step000012_L0+L1.obj")
    assert export_path(Path("run"), 12, "obj") == Path("run/exports/curves_step000012.obj")


def test_a_layer_selection_keeps_every_per_primitive_array_aligned():
    """The view-dependent opacity's b goes with its primitives (extraction reads it)."""
    dirs = np.arange(15.0).reshape(5, 3)
    snapshot = dataclasses.replace(snapshot_of_layers([0, 1, 0, 1, 1]), opacity_dirs=dirs)
    only_l1 = visible_subset(snapshot, {"L0": False})
    np.testing.assert_array_equal(only_l1.opacity_dirs, snapshot.opacity_dirs[[1, 3, 4]])
    primitives = only_l1.primitives
    assert {len(getattr(primitives, name)) for name in ("means", "opacity", "opacity_dirs")} == {3}


def test_the_folder_browser_lists_folders_and_says_what_they_are(tmp_path):
    scene = write_box_scene(tmp_path / "box", views=2, size=32)
    write_run(RunFolder(tmp_path / "a run", scene, "preview", preset("preview")))
    (tmp_path / ".hidden").mkdir()
    (tmp_path / "plain").mkdir()
    (tmp_path / "a file").write_text("")
    names, note = sub_folders(tmp_path)
    assert names == ["a run", "box", "plain"] and note == ""
    assert folder_kind(tmp_path / "a run") == "run" and folder_kind(tmp_path / "plain") == ""
    assert folder_kind(scene) == "nerf scene"
    assert sub_folders(tmp_path / "missing")[1].startswith("cannot read this folder")


def test_scripted_keys_are_checked():
    assert len(press("ctrl+o")) == 1 and len(press("1")) == 1
    with pytest.raises(ValueError, match="unknown key"):
        press("hyper+x")


def test_an_aborted_start_leaves_no_folder_but_a_trained_one_stays(tmp_path):
    layered = tmp_path / "layered"
    for folder in (layered, layered / "L0", layered / "L1"):
        folder.mkdir()
        (folder / "config.json").write_text("{}")
    (layered / "layers.json").write_text("{}")
    (layered / LOCK_FILE).write_text("")
    discard_scaffold(layered)
    assert not layered.exists()
    trained = tmp_path / "trained"
    trained.mkdir()
    (trained / "config.json").write_text("{}")
    (trained / "checkpoint.pt").write_bytes(b"")
    discard_scaffold(trained)
    assert (trained / "checkpoint.pt").is_file() and (trained / "config.json").is_file()


def test_the_benchmark_help_ends_with_a_sentence(capsys):
    from edgedog.bench.studio import main

    with pytest.raises(SystemExit):
        main(["--help"])
    help_text = capsys.readouterr().out
    description = help_text.split("\n\n")[1]
    assert description.rstrip().endswith(".")


def test_a_moving_rate_follows_the_last_seconds_not_the_average():
    from edgedog.app.rates import MovingRate

    rate = MovingRate(seconds=2.0)
    assert rate.rate == 0.0
    for second in range(11):  # 10 a second for 10 s, then 2 a second
        rate.add(float(second), 10.0 * second)
    assert rate.rate == pytest.approx(10.0)
    for second in range(11, 15):
        rate.add(float(second), 100.0 + 2.0 * (second - 10))
    assert rate.rate == pytest.approx(2.0)  # the run's average would still say 7.6


def test_a_key_draws_the_next_frame_at_once_and_a_mouse_move_only_at_the_capped_rate(monkeypatch):
    from edgedog.app import window

    class Watch:
        keys, active = 0, False

    watch, events = Watch(), []

    def wait_events_timeout(seconds: float) -> None:  # the next event comes after 10 ms
        time.sleep(min(seconds, 0.01))
        events.append(seconds)
        if len(events) == 1:
            watch.active = True  # a mouse move: the interactive rate (cap) from now on
        elif len(events) == 3:
            watch.keys += 1  # a key

    monkeypatch.setattr(window.glfw, "wait_events_timeout", wait_events_timeout)
    started = time.perf_counter()
    window._wait_for_next_frame(watch, 2.0, 2.0, started)  # idle 2 fps, capped at 2 fps: up to 0.5 s
    assert len(events) == 3 and time.perf_counter() - started < 0.2  # the key ended the wait
    events.clear()
    watch.keys, started = 0, time.perf_counter()
    window._wait_for_next_frame(watch, 50.0, 2.0, started)  # active: at most 1/50 s, mouse moves or not
    assert time.perf_counter() - started < 0.05


def test_a_frame_is_drawn_only_when_it_differs_from_the_one_shown():
    import ctypes
    from types import SimpleNamespace

    from edgedog.app.redraw import VERTEX_BYTES, Redraw
    from imgui_bundle import imgui

    vertices = ctypes.create_string_buffer(3 * VERTEX_BYTES)
    buffer = SimpleNamespace(size=lambda: 3, data_address=lambda: ctypes.addressof(vertices))
    draw_list = SimpleNamespace(vtx_buffer=buffer, cmd_buffer=SimpleNamespace(size=lambda: 1))
    texture = SimpleNamespace(status=imgui.ImTextureStatus.ok)
    frame = SimpleNamespace(display_size=imgui.ImVec2(800, 600), cmd_lists=[draw_list], textures=[texture])
    redraw = Redraw()
    assert redraw.needed(frame, pictures=0) and not redraw.needed(frame, pictures=0)
    vertices[VERTEX_BYTES + 1] = b"\x01"  # a vertex moved
    assert redraw.needed(frame, pictures=0) and not redraw.needed(frame, pictures=0)
    assert redraw.needed(frame, pictures=1)  # the 3D view or an inspector was re-drawn
    texture.status = imgui.ImTextureStatus.want_updates  # e.g. new glyphs for the font atlas
    assert redraw.needed(frame, pictures=1)


def test_with_a_kept_back_buffer_only_the_panels_that_changed_are_drawn_again():
    import ctypes
    from types import SimpleNamespace

    import numpy as np
    from edgedog.app.redraw import Redraw, aligned, clip_rects, clip_to, pixel_box
    from imgui_bundle import imgui

    class Commands(list):
        def size(self) -> int:
            return len(self)

    def panel(name: str, x0: float, y0: float, x1: float, y1: float):
        """A draw list: one quad's 4 vertices spanning the rectangle, one command clipped to the
        display (as a panel's first command is)."""
        vertices = np.zeros((4, 5), np.float32)
        vertices[:, :2] = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        data = ctypes.create_string_buffer(vertices.tobytes(), vertices.nbytes)
        return SimpleNamespace(_owner_name=name, data=data, vtx_buffer=SimpleNamespace(
            size=lambda: 4, data_address=lambda: ctypes.addressof(data)),
            cmd_buffer=Commands([SimpleNamespace(clip_rect=imgui.ImVec4(0, 0, 800, 600))]))

    lists = [panel("Controls", 0, 0, 200, 600), panel("3D view", 200, 0, 800, 400),
             panel("##status", 0, 580, 800, 600)]
    frame = SimpleNamespace(display_size=imgui.ImVec2(800, 600), display_pos=imgui.ImVec2(0, 0),
                            framebuffer_scale=imgui.ImVec2(1, 1), cmd_lists=lists, textures=[])
    redraw = Redraw(partial=True)
    pictures = {"3D view": 0, "Inspectors": 0}
    assert redraw.needed(frame, pictures) and redraw.region is None  # the first frame: whole
    assert not redraw.needed(frame, pictures)
    # The view re-drawn: the view alone; the status line's text changed: the status line alone.
    assert redraw.needed(frame, {**pictures, "3D view": 1}) and redraw.region == (200, 0, 800, 400)
    ctypes.memmove(lists[2].data, np.float32([0, 579]).tobytes(), 8)  # a vertex moved up a pixel
    assert redraw.needed(frame, {**pictures, "3D view": 1}) and redraw.region == (0, 579, 800, 600)
    # Both: the rectangle around them covers most of the window, which is drawn whole.
    ctypes.memmove(lists[2].data, np.float32([0, 580]).tobytes(), 8)
    assert redraw.needed(frame, {**pictures, "3D view": 2}) and redraw.region is None
    assert pixel_box((200, 0, 800, 400), frame, 600) == (200, 200, 600, 400)  # GL's y from the bottom
    # A fractional region (a border's vertices lie on pixel centres) is widened to whole pixels, so
    # that the renderer's scissor covers every pixel the clear touched.
    assert aligned((329.5, 0.5, 998.5, 413.5), frame) == (329, 0, 999, 414)
    # Drawing a region clips every command to it.
    original = clip_rects(frame)
    clip_to(frame, (200, 0, 800, 400), original)
    clip = lists[0].cmd_buffer[0].clip_rect
    assert (clip.x, clip.y, clip.z, clip.w) == (200, 0, 800, 400)  # was the whole display
    clip_to(frame, (0, 579, 800, 600), original)  # the next region: from the clip rects as they were
    clip = lists[0].cmd_buffer[0].clip_rect
    assert (clip.x, clip.y, clip.z, clip.w) == (0, 579, 800, 600)
    # Without a kept back buffer any change draws the whole frame; an exposed window is drawn whole.
    whole = Redraw()
    assert whole.needed(frame, pictures) and whole.region is None
    redraw.invalidate()
    assert redraw.needed(frame, {**pictures, "3D view": 1}) and redraw.region is None


def test_each_region_clips_imguis_own_draw_commands_from_their_clip_rects_as_built():
    from edgedog.app.redraw import clip_rects, clip_to
    from imgui_bundle import imgui

    context = imgui.create_context()
    try:
        io = imgui.get_io()
        io.set_ini_filename(None)  # as the studio: no imgui.ini left in the working folder
        io.display_size = imgui.ImVec2(800, 600)
        io.backend_flags |= imgui.BackendFlags_.renderer_has_textures  # no font atlas to upload
        for _ in range(2):  # a new window shows from its second frame
            imgui.new_frame()
            imgui.set_next_window_pos(imgui.ImVec2(10, 10))
            imgui.begin("A")
            imgui.text("hello")
            imgui.end()
            imgui.render()
        frame = imgui.get_draw_data()
        original = clip_rects(frame)
        for region in [(0, 0, 50, 50), (100, 100, 200, 200)]:
            clip_to(frame, region, original)
            for draw_list, clips in zip(frame.cmd_lists, original):
                for index, built in enumerate(clips):
                    clip = draw_list.cmd_buffer[index].clip_rect
                    assert (clip.x, clip.y, clip.z, clip.w) == (
                        max(built[0], region[0]), max(built[1], region[1]),
                        min(built[2], region[2]), min(built[3], region[3]))
    finally:
        imgui.destroy_context(context)
