"""The studio, one frame at a time: acts on the UI's requests, keeps the run's controls in step
with the UI, refreshes the 3D view, inspectors and curves from the latest snapshot, and draws
the panels. Window-independent: `window.py` owns GLFW, imgui's backends and the frame loop.

A folder of photos opened is offered structure from motion (`edgedog sfm` in a child process,
sfm_job.py); once its cameras are recovered, their scene opens like any other, its sparse points
shown, and trains.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import moderngl
from edgedog.app import controls_panel, inspector_panel, layout, plots_panel, shortcuts, view_panel, widgets
from edgedog.app.colors import COLORMAPS, colorbar
from edgedog.app.confirm import Confirm
from edgedog.app.display import TITLE
from edgedog.app.extraction import Extraction, extract_snapshot
from edgedog.app.folder_dialog import PHOTOS, FolderDialog, folder_kind
from edgedog.app.inspection import NAMES as INSPECTOR_NAMES
from edgedog.app.inspection import Inspector, inspect_view
from edgedog.app.jobs import BackgroundJob, Done
from edgedog.app.layers import finest, layer_members, selection, visible_subset
from edgedog.app.photos import offer, sfm_scene_folder
from edgedog.app.points_view import PointsView
from edgedog.app.rates import MovingRate
from edgedog.app.saved_run import read_extraction
from edgedog.app.session import Session
from edgedog.app.sfm_job import CANCELLED, DONE, SfmJob, SfmOutcome
from edgedog.app.state import EXPORT_FORMATS, LiveSettings, Request, UIState
from edgedog.app.textures import ImageTexture
from edgedog.app.worker import FINISHED, TRAINING, Published, TrainingWorker
from imgui_bundle import imgui

from edgedog.curve_files import EdgeCurves
from edgedog.errors import EdgeDogError
from edgedog.scenes.sfm import photo_names

INSPECT_EVERY, INSPECT_SHARE = 1.0, 0.1
"""Seconds between the starts of two inspector renders: at least INSPECT_EVERY; and, for a newer
snapshot alone, long enough for them to take at most INSPECT_SHARE of the time (they share the
CPU with the training)."""
WINDOW_REQUESTS = ("screenshot", "close")
"""Requests the window acts on (it owns the framebuffer and the loop)."""
CONFIRMED = "confirmed"
"""The argument a request carries once the user has confirmed it (see `Studio._go_ahead`)."""
FOCUS_WINDOW = "3D view"
"""The panel that takes imgui's focus back whenever a window over the panels closes."""


def ui_cpu_seconds() -> float:
    """CPU seconds of the window's own threads so far: the calling (main) thread's and those of a
    software OpenGL's rasterizer (llvmpipe); what the UI takes from the training's CPU, for the
    studio benchmark (Linux; elsewhere the main thread's alone)."""
    total = time.thread_time()
    try:
        for task in os.scandir("/proc/self/task"):
            with open(f"{task.path}/comm") as comm:
                if not comm.read().startswith("llvmpipe"):
                    continue
            with open(f"{task.path}/schedstat") as schedstat:  # nanoseconds on the CPU first
                total += int(schedstat.read().split()[0]) / 1e9
    except (OSError, ValueError, IndexError):  # no /proc, or a thread that ended meanwhile
        pass
    return total


def written_note(extraction: Extraction) -> str:
    """What an extraction exported, short enough for the status line: the files' names in the
    run's exports folder, or why nothing was written."""
    if extraction.unwritten:
        return f"; nothing exported ({', '.join(extraction.unwritten)}): no curves in this snapshot"
    if not extraction.written:
        return ""
    first, *others = extraction.written
    return f"; wrote {first.parent.name}/{first.name}{''.join(f', {path.suffix}' for path in others)}"


class Studio:
    """The session on screen.

    Attributes:
        session: the scene and its runs; state: the UI state; view: the 3D view.
        sfm: the structure from motion under way (or last run); sfm_outcome: how the last ended.
        inspectors: the latest inspector images; extraction: the latest curves.
        fscores: (elapsed, {mm: F}) per scored extraction of the current run's whole model.
        exports: every file exported in this window; stop_seconds: how long closing took.
    """

    def __init__(self, ctx: moderngl.Context, session: Session, runs_root: Path | None = None):
        self.ctx, self.runs_root = ctx, runs_root
        self.view = PointsView(ctx)
        self.sfm: SfmJob | None = None
        self.sfm_outcome: SfmOutcome | None = None
        self.inspector_job, self.extract_job = BackgroundJob("inspect"), BackgroundJob("extract")
        self.textures = [ImageTexture(ctx) for _ in INSPECTOR_NAMES]
        self.colorbars = {name: ImageTexture(ctx, moderngl.LINEAR) for name in COLORMAPS}
        for name, texture in self.colorbars.items():
            texture.set(colorbar(name))
        self.exports: list[Path] = []
        self.stop_seconds: float | None = None
        self.frames = 0
        """Frames built (`frame` calls)."""
        self.frames_drawn = 0
        """Frames the window drew and showed (it skips those that repeat the last: redraw.py)."""
        self.frame_rate = MovingRate()
        """Frames drawn per second, now."""
        self.inspector_uploads = 0
        """Inspector images uploaded (a frame that shows new ones is drawn)."""
        self.typed_drawn: list[tuple[float, int]] = []
        """(time.monotonic(), characters typed so far) when a frame showed newly typed ones: the
        window's (display.InputWatch.drawn), for the studio benchmark's input latency."""
        self.dialog: FolderDialog | None = None
        self.plots_tabbed = False
        """Whether the plots panel showed its plots in tabs (too short to stack them)."""
        self.confirm: Confirm | None = None
        """The question asked before stopping a run (quit, Restart, open), while it waits."""
        self._overlays: set[str] = set()
        self._open(session)

    # --- sessions and runs
    def _open(self, session: Session) -> None:
        self.session = session
        self.state = UIState.for_config(session.preset, session.config)
        scene = session.scene
        self.view.set_scene(scene.cameras, scene.bounds, session.ground_truth)
        self.view.set_points(scene.sfm_points, scene.sfm_colors)
        self._reset_run()
        if session.resume is not None:  # Restart keeps the run's number of layers
            self.state.restart.layers = len(session.resume.layers())
        saved = session.saved
        if saved is not None and saved.extraction is not None:  # a finished run shows its curves
            self._show_extraction(saved.extraction)
            self._extracted = (*self.run_token, saved.latest.version)

    def _reset_run(self) -> None:
        self.inspectors: list[Inspector] = []
        self.inspected_layers: str | None = None
        """The layers the inspectors show, e.g. 'L0+L1'."""
        self.extraction: Extraction | None = None
        self.fscores: list[tuple[float, dict[int, float]]] = []
        self.step_rate = MovingRate()
        """The current run's training steps per second, now."""
        self._applied_live: LiveSettings | None = None  # pushed to the next worker at once
        self._inspected = self._extracted = None
        self._last_inspect = self._last_extract = 0.0
        self._inspect_seconds = 0.0  # how long the last inspector render took
        self._pending_exports: list[str] = []
        self._extract_asked = False

    def _start(self, fresh: bool) -> None:
        restart = self.state.restart
        config = restart.apply(self.session.base_config(restart.preset), self.state.live)
        resuming = self.session.resumable and not fresh
        self.session.start(restart.preset, config, fresh=fresh, layers=restart.layers)
        fscores = self.fscores if resuming else []  # a resumed run's plots go on
        self._reset_run()
        self.fscores = fscores
        self.state.status = f"training into {self.session.run_dir}"

    @property
    def run_token(self) -> tuple[int, int]:
        """Identifies the current run across sessions (what job keys start with)."""
        return id(self.session), self.session.runs

    @property
    def worker(self) -> TrainingWorker | None:
        """The current run's worker, or the finished run opened (read like one)."""
        return self.session.worker

    @property
    def training(self) -> bool:
        """Whether a run is training now (the window then caps its frame rate lower)."""
        return self.worker is not None and self.worker.phase == TRAINING

    @property
    def running(self) -> bool:
        """Whether a run is under way (setting up, training, paused or extracting its final curves)
        or structure from motion: what quitting, Restart or opening another folder would stop."""
        return (self.worker is not None and self.worker.alive) or self.recovering

    @property
    def recovering(self) -> bool:
        """Whether structure from motion is under way."""
        return self.sfm is not None and self.sfm.busy

    @property
    def stops(self) -> str | None:
        """What quitting or opening another folder would stop now, in words (None: nothing)."""
        if self.recovering:
            return "the camera recovery (nothing of it is kept)"
        return "the run under way (it keeps its last checkpoint)" if self.running else None

    @property
    def latest(self) -> Published | None:
        return None if self.worker is None else self.worker.latest

    @property
    def overlays(self) -> set[str]:
        """The windows open over the panels: 'help', 'browser', 'confirm'."""
        return {name for name, shown in (("help", self.state.show_help), ("browser", self.dialog is not None),
                                         ("confirm", self.confirm is not None)) if shown}

    def close_top(self) -> bool:
        """Close the topmost of the folder browser and the help (Esc); whether one was open."""
        if self.dialog is not None:
            self.dialog = None
        elif self.state.show_help:
            self.state.show_help = False
        else:
            return False
        return True

    # --- one frame
    def frame(self) -> list[Request]:
        """Update and draw everything; returns the requests only the window can act on."""
        self.frames += 1
        now = time.monotonic()
        self.frame_rate.add(now, self.frames_drawn)
        if self.worker is not None:
            self.step_rate.add(now, self.worker.steps)
        shortcuts.handle_keys(self)
        window_requests = [r for r in self.state.take_requests() if not self._handle(r)]
        self.session.reap()
        self._poll_sfm()
        self._sync_live()
        self._poll_jobs()
        latest = self.latest
        info = None if self.worker is None else self.worker.info
        self.view.sync(latest, None if info is None else info.raster, self.state.display, self.state.view,
                       self.shown_curves)
        self.view.sync_points(self.state.display.sfm_points)
        self._refresh_inspectors(latest)
        self._refresh_curves(latest)
        self._draw()
        return window_requests

    def _handle(self, request: Request) -> bool:
        """Act on a request; False for those the window acts on."""
        if request.name in WINDOW_REQUESTS:
            return False
        try:
            if request.name == "quit":
                self._quit(request)
            elif request.name == "open":
                self._request_open(request)
            elif request.name == "sfm":
                self._start_sfm(Path(request.args["photos"]), request.args.get("out"))
            elif request.name == "cancel_sfm":
                self._cancel_sfm()
            elif request.name in ("start", "restart") and self.recovering:
                self.state.status = f"{request.name}: cameras are being recovered; wait for them or Cancel"
            elif request.name == "restart" and self._go_ahead(
                    request, "Stop this run and train a new run folder? It keeps its last checkpoint.",
                    "Restart"):
                self._start(fresh=True)
            elif request.name == "start":
                self._start(fresh=False)
            elif request.name in ("pause", "resume") and self.worker is not None:
                self.worker.update_controls(paused=request.name == "pause")
            elif request.name in ("extract", "export") and self.latest is None:
                self.state.status = f"nothing to {request.name} yet: start a run"
            elif request.name in ("extract", "export") and self.selection is None:
                self.state.status = f"nothing to {request.name}: every layer is hidden (tick one in 3D view)"
            elif request.name == "extract":
                self._extract_asked = True
            elif request.name == "export":
                self._request_export(request.args)
            elif request.name == "snap":
                self.view.snap(self.state.view)
            elif request.name == "reset_view":
                self.view.reset()
            elif request.name == "help":
                self.state.show_help = not self.state.show_help
        except EdgeDogError as error:
            self.state.status = f"error: {error}"
        return True

    def _go_ahead(self, request: Request, question: str, yes: str, ask: bool = False) -> bool:
        """Whether `request` may act now: at once when it stops no run (and `ask` is False) or once
        confirmed; otherwise the question is asked, and a yes makes the request again, confirmed."""
        if request.args.get(CONFIRMED) or not (ask or self.running):
            return True
        self.confirm = Confirm(question, yes, Request(request.name, {**request.args, CONFIRMED: True}))
        return False

    def _quit(self, request: Request) -> None:
        """q, Esc with nothing open (`ask`: it always asks) or the window's close button."""
        question = ("Cancel the camera recovery and quit?" if self.recovering else
                    "Stop training and quit? The run keeps its last checkpoint." if self.running
                    else "Quit EdgeDoG Studio?")
        if self._go_ahead(request, question, "Quit", ask=request.args.get("ask", False)):
            self.state.request("close")

    def _request_open(self, request: Request) -> None:
        """Open the request's path (once confirmed while a run is under way), or show the folder
        browser when it has none."""
        path = request.args.get("path")
        if path is None:
            self.dialog = FolderDialog(self.session.opened)
            return
        if folder_kind(Path(path).expanduser()) == PHOTOS:
            self._offer_sfm(Path(path).expanduser().resolve())
            return
        question = (f"Cancel the camera recovery and open {path}?" if self.recovering else
                    f"Stop this run and open {path}? It keeps its last checkpoint.")
        if not self._go_ahead(request, question, "Open"):
            return
        self._open_scene(self._session(path))

    def _session(self, path: str | Path) -> Session:
        """The session of a scene or run folder, with this one's preset and overrides."""
        return Session.open(path, self.runs_root, self.state.restart.preset, self.session.overrides)

    def _open_scene(self, session: Session) -> None:
        """Show `session` instead of the one open (whose run stops, keeping its last checkpoint)."""
        self._cancel_sfm(wait=True)
        self.session.stop()
        if self.sfm is not None and session.scene_path != self.sfm.out.resolve():
            self.sfm = self.sfm_outcome = None  # the panel tells of photos no longer shown
        self._open(session)
        self.state.status = f"opened {session.opened}"

    # --- photos: structure from motion
    @property
    def sfm_root(self) -> Path:
        """Where the scenes recovered from photos go: beside the runs."""
        return self.runs_root or self.session.runs_root

    def _offer_sfm(self, photos: Path) -> None:
        """Ask whether to recover the cameras of a folder of photos (an InputError when it has too
        few, or when the studio would have to write inside it)."""
        count = len(photo_names(photos))
        out = sfm_scene_folder(self.sfm_root, photos)
        request = Request("sfm", {"photos": str(photos), "out": str(out)})
        self.confirm = Confirm(offer(photos, count, out, self.stops), "Recover cameras (SfM)", request)

    def _start_sfm(self, photos: Path, out: str | None) -> None:
        """Stop what runs and start `edgedog sfm` on `photos` into `out` (default: a new folder
        beside the runs)."""
        out_path = Path(out) if out else sfm_scene_folder(self.sfm_root, photos)
        self._cancel_sfm(wait=True)
        self.session.stop()
        settings = self.state.sfm
        job = SfmJob(photos, out_path, settings.matcher, settings.max_image_size)
        job.start()
        self.sfm, self.sfm_outcome = job, None
        self.state.status = f"recovering the cameras of {photos} into {out_path}"

    def _cancel_sfm(self, wait: bool = False) -> None:
        """Stop the structure from motion under way (what it wrote is removed); with `wait`, until
        it has ended and been taken."""
        if self.recovering:
            self.sfm.cancel(None if wait else 0.0)
            self.state.status = "cancelling the camera recovery"
            if wait:
                self._poll_sfm()

    def _poll_sfm(self) -> None:
        """Take a finished structure from motion: open its scene (and train), or say why not."""
        outcome = None if self.sfm is None else self.sfm.poll()
        if outcome is None:
            return
        self.sfm_outcome = outcome
        if outcome.status == DONE:
            self._take_sfm(outcome)
        elif outcome.status == CANCELLED:
            self.state.status = "camera recovery cancelled: nothing was written"
        else:
            self.state.status = f"structure from motion failed: {outcome.error}"

    def _take_sfm(self, outcome: SfmOutcome) -> None:
        """Open the scene recovered, its cameras and points shown, then train if asked to."""
        try:
            session = self._session(outcome.out)
        except EdgeDogError as error:
            self.state.status = f"error: {error}"
            return
        self._open_scene(session)
        progress = outcome.progress
        self.state.status = (f"cameras of {progress.registered} of {progress.photos} photos and "
                             f"{progress.points} points in {outcome.seconds:.0f} s: {outcome.out}")
        if self.state.sfm.train_after:
            self._start(fresh=False)

    def _request_export(self, args: dict) -> None:
        """Queue one export of the latest snapshot in the formats asked for (default: the checked
        ones); every format of one request comes from the same extraction."""
        formats = args.get("formats") or ([args["format"]] if "format" in args else
                                          [fmt for fmt in EXPORT_FORMATS if self.state.export_formats[fmt]])
        if not formats:
            self.state.status = "nothing to export: check a format (PLY, OBJ, JSON)"
        for fmt in formats:
            if fmt not in self._pending_exports:
                self._pending_exports.append(fmt)

    def _draw_dialog(self) -> None:
        if self.dialog is None:
            return
        chosen = self.dialog.draw()
        if chosen is not None:
            self.state.request("open", path=str(chosen))
        if not self.dialog.open:
            self.dialog = None

    def _sync_live(self) -> None:
        """Send changed live settings to the worker (applied at its next step boundary)."""
        if self.worker is not None and self.state.live != self._applied_live:
            live = self.state.live
            self.worker.update_controls(keep_ratio=live.keep_ratio, weighting=live.weighting)
            self._applied_live = LiveSettings(live.keep_ratio, live.weighting)

    def _poll_jobs(self) -> None:
        done = self.inspector_job.poll()
        if done is not None:
            self._inspect_seconds = done.seconds
        if done is not None and self._current(done):
            self._show_inspectors(done)
        done = self.extract_job.poll()
        if done is not None and self._current(done):
            self._take_extraction(done)

    def _current(self, done: Done) -> bool:
        """Whether a job's outcome belongs to the current run (not one replaced since)."""
        return done.key[:2] == self.run_token

    def _show_inspectors(self, done: Done) -> None:
        if done.error:  # no images rather than those of other layers or another view
            self.inspectors, self.inspected_layers = [], None
            self.state.status = f"inspectors: {done.error}"
            return
        self.inspectors, self.inspected_layers = done.value, "+".join(done.key[-1])
        for texture, inspector in zip(self.textures, self.inspectors):
            texture.set(inspector.rgba)
        self.inspector_uploads += 1

    def _take_extraction(self, done: Done) -> None:
        if done.error:
            self.state.status = f"extraction: {done.error}"
            return
        self._show_extraction(done.value)

    def _show_extraction(self, extraction: Extraction) -> None:
        self.extraction = extraction
        if extraction.fscore is not None and not extraction.selection:  # the plot follows the whole model
            self.fscores.append((extraction.elapsed, extraction.fscore))
        self.exports += extraction.written
        counts = f"{len(extraction.curves.lines)} lines, {len(extraction.curves.beziers)} Beziers"
        layers = f" ({extraction.selection})" if extraction.selection else ""
        self.state.status = f"curves at step {extraction.step}{layers}: {counts}{written_note(extraction)}"

    def _refresh_inspectors(self, latest: Published | None) -> None:
        """Re-render the inspectors when the snapshot, the view or the weighting changed."""
        info = None if self.worker is None else self.worker.info
        scene = self.session.scene
        shown = self.state.display.layers
        detector = info.detector if info else (scene.detectors[0] if scene.detectors else None)
        if info is not None and latest is not None:  # the maps of the finest layer shown
            detector = self.worker.detectors.get(finest(latest.snapshot, shown), detector)
        weighting = self.state.live.weighting
        key = (*self.run_token, None if latest is None else latest.version, self.state.view, weighting,
               detector, tuple(sorted(name for name, on in shown.items() if on)))
        now = time.monotonic()
        last = self._inspected
        newer_only = last is not None and key[:2] + key[3:] == last[:2] + last[3:]  # another version only
        wait = max(INSPECT_EVERY, self._inspect_seconds / INSPECT_SHARE) if newer_only else INSPECT_EVERY
        if key == self._inspected or now - self._last_inspect < wait:
            return
        # The 2D render shows the layers the 3D view shows.
        snapshot = visible_subset(latest.snapshot, shown) if latest is not None and info is not None else None
        raster = None if info is None else info.raster
        view = min(self.state.view, len(scene) - 1)
        pixel_uncertainty = self.session.run_config.loss.pixel_uncertainty
        if self.inspector_job.submit(key, lambda: inspect_view(snapshot, scene, view, detector, raster,
                                                               weighting, pixel_uncertainty)):
            self._inspected, self._last_inspect = key, now

    @property
    def selection(self) -> str | None:
        """The layers shown ('' all of them, None none), as extractions name their selection."""
        latest, shown = self.latest, self.state.display.layers
        if latest is None or finest(latest.snapshot, shown) is None:
            return None
        return selection(latest.snapshot, shown)

    @property
    def shown_curves(self) -> EdgeCurves | None:
        """The curves of the layers shown (none while those of another selection are all there is)."""
        extraction = self.extraction
        if extraction is None or extraction.selection != self.selection:
            return None
        return extraction.curves

    def _refresh_curves(self, latest: Published | None) -> None:
        """Extract when asked (exports), on the auto timer, once for a finished run's result, and
        when the layers shown change; always the layers shown."""
        worker, chosen = self.worker, self.selection
        if latest is None or worker is None or worker.info is None or self.extract_job.busy or chosen is None:
            return
        now = time.monotonic()
        asked = self._extract_asked or bool(self._pending_exports)
        timer = self.state.auto_extract and now - self._last_extract >= self.state.auto_extract_seconds
        other_layers = self.extraction is not None and self.extraction.selection != chosen
        key = (*self.run_token, latest.version, chosen)
        if not (asked or ((timer or worker.phase == FINISHED or other_layers) and key != self._extracted)):
            return
        if worker.phase == FINISHED and not asked and not chosen:  # the run's own final curves
            extraction = read_extraction(self.session.curves_folder, latest.snapshot.step, latest.elapsed)
            if extraction is not None:
                self._show_extraction(extraction)
                self._extracted = key
                return
        self._submit_extraction(key, latest, chosen)
        self._extracted, self._last_extract = key, now

    def _submit_extraction(self, key: tuple, latest: Published, chosen: str) -> None:
        """Extract the layers `chosen` of the latest snapshot, exporting the formats asked for."""
        shown = self.state.display.layers
        snapshot = visible_subset(latest.snapshot, shown) if chosen else latest.snapshot
        # As `edgedog train --layers`: the projection filter of a selection uses its finest layer's maps.
        detector = self.worker.detectors.get(finest(latest.snapshot, shown), self.worker.info.detector)
        formats, scene, run_dir = self._pending_exports, self.session.scene, self.session.run_dir
        self.extract_job.submit(key, lambda: extract_snapshot(snapshot, latest.elapsed, scene, detector,
                                                              run_dir, formats, selection=chosen))
        self._pending_exports, self._extract_asked = [], False

    def _draw(self) -> None:
        widgets.RECTS.clear()
        widgets.CUT.clear()
        areas = layout.studio_layout()
        controls_panel.draw(self, areas["controls"])
        view_panel.draw(self, areas["view"])
        plots_panel.draw(self, areas["plots"])
        inspector_panel.draw(self, areas["inspectors"])
        controls_panel.draw_status(self, areas["status"])
        shortcuts.draw_help(self)
        self._draw_dialog()
        self._draw_confirm()
        overlays = self.overlays
        if self._overlays - overlays:  # one closed: the keys go to the panels again
            imgui.set_window_focus(FOCUS_WINDOW)
        self._overlays = overlays

    def _draw_confirm(self) -> None:
        if self.confirm is None:
            return
        answer = self.confirm.draw()
        if answer:
            self.state.requests.append(self.confirm.request)
        if answer is not None:
            self.confirm = None

    @property
    def pictures(self) -> dict[str, int]:
        """Counts the re-drawn images the panels show, by the window that shows them (the 3D
        view's and the inspectors')."""
        return {"3D view": self.view.renders, "Inspectors": self.inspector_uploads}

    @property
    def title(self) -> str:
        """The window's title: the scene and the run shown."""
        run = self.session.run_dir
        return f"{self.session.scene_path.name} - {run.name if run else 'no run'} - {TITLE}"

    # --- probes and closing
    def probe(self) -> dict:
        """Flat facts for the scripted driver and its report."""
        worker = self.worker
        sfm = None if self.sfm is None else self.sfm.progress
        outcome = self.sfm_outcome
        facts = {"phase": None if worker is None else worker.phase, "runs": self.session.runs,
                 "sfm": "running" if self.recovering else None if outcome is None else outcome.status,
                 "sfm_stage": None if sfm is None else sfm.stage_name,
                 "sfm_fraction": None if sfm is None else sfm.fraction,
                 "sfm_error": None if outcome is None else outcome.error,
                 "sfm_out": None if self.sfm is None else str(self.sfm.out),
                 "sfm_points": self.view.points_shown, "scene": str(self.session.scene_path),
                 "steps": 0 if worker is None else worker.steps,
                 "steps_per_second": 0.0 if worker is None else worker.steps_per_second,
                 "steps_per_second_now": self.step_rate.rate, "fps_now": self.frame_rate.rate,
                 "error": None if worker is None else worker.error,
                 "version": None if self.latest is None else self.latest.version,
                 "splats_uploaded": self.view.splats.count, "splats_drawn": self.view.drawn,
                 "inspectors": len(self.inspectors), "inspected_layers": self.inspected_layers,
                 "exports": len(self.exports),
                 "export_paths": [str(path) for path in self.exports],
                 "fscores": len(self.fscores), "status": self.state.status,
                 "run_dir": None if worker is None or worker.info is None else str(worker.info.run_dir),
                 "curves": None if self.extraction is None else self.extraction.curves.num_curves,
                 "extracting": self.extract_job.pending or self._extract_asked or bool(self._pending_exports),
                 "curves_selection": None if self.extraction is None else self.extraction.selection,
                 "layers": None if self.latest is None else sorted(layer_members(self.latest.snapshot)),
                 "series": 0 if worker is None else len(worker.series()),
                 "loss": None if self.latest is None else self.latest.snapshot.loss,
                 "elapsed": None if self.latest is None else self.latest.elapsed,
                 "view_at_home": self.view.at_home, "view_index": self.state.view,
                 "frames": self.frames, "frames_drawn": self.frames_drawn, "view_renders": self.view.renders,
                 "cpu_seconds": time.process_time(), "ui_cpu_seconds": ui_cpu_seconds(),
                 "help": self.state.show_help, "cut_widgets": sorted(widgets.CUT),
                 "plots_tabbed": self.plots_tabbed,
                 "dialog": None if self.dialog is None else str(self.dialog.path),
                 "dialog_text": None if self.dialog is None else self.dialog.typed,
                 "typed_drawn": self.typed_drawn,
                 "confirm": None if self.confirm is None else self.confirm.question,
                 "title": self.title}
        controls = None if worker is None else worker.trainer_controls()
        facts.update({f"controls.{name}": value for name, value in (controls or {}).items()})
        return facts

    def close(self) -> None:
        """Stop the run (within a second once it trains: it keeps its last checkpoint), wait for
        what cannot be interrupted (a trainer's set-up, an extraction), and free GL objects."""
        started = time.perf_counter()
        self._cancel_sfm(wait=True)
        if not self.session.stop(1.0):
            print("edgedog: waiting for the run's set-up to finish (it cannot be interrupted)...",
                  file=sys.stderr, flush=True)
            self.session.stop(None)
        self.stop_seconds = time.perf_counter() - started
        for job in (self.inspector_job, self.extract_job):
            job.wait(None)
        self.view.release()
        for texture in [*self.textures, *self.colorbars.values()]:
            texture.release()
