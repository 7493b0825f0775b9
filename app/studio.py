"""The studio, one frame at a time: acts on the UI's requests, keeps the run's controls in step
with the UI, refreshes the 3D view, inspectors and curves from the latest snapshot, and draws
the panels. Window-independent: `window.py` owns GLFW, imgui's backends and the frame loop.
"""

from __future__ import annotations

import time
from pathlib import Path

import moderngl
from edgedog.app import controls_panel, inspector_panel, layout, plots_panel, view_panel
from edgedog.app.colors import COLORMAPS, colorbar
from edgedog.app.extraction import Extraction, extract_snapshot
from edgedog.app.inspection import NAMES as INSPECTOR_NAMES
from edgedog.app.inspection import Inspector, inspect_view
from edgedog.app.jobs import BackgroundJob, Done
from edgedog.app.layers import visible_subset
from edgedog.app.session import Session
from edgedog.app.state import LiveSettings, Request, UIState
from edgedog.app.textures import ImageTexture
from edgedog.app.view3d import View3D
from edgedog.app.worker import FINISHED, Published, TrainingWorker
from imgui_bundle import portable_file_dialogs as pfd

from edgedog.errors import EdgeDogError

INSPECT_EVERY = 1.0
"""Seconds between two inspector renders while training (they share the CPU with it)."""
WINDOW_REQUESTS = ("screenshot", "close")
"""Requests the window acts on (it owns the framebuffer and the loop)."""


class Studio:
    """The session on screen.

    Attributes:
        session: the scene and its runs; state: the UI state; view: the 3D view.
        inspectors: the latest inspector images; extraction: the latest curves.
        fscores: (elapsed, {mm: F}) per scored extraction of the current run.
        exports: every file exported in this window; stop_seconds: how long closing took.
    """

    def __init__(self, ctx: moderngl.Context, session: Session, runs_root: Path | None = None):
        self.ctx, self.runs_root = ctx, runs_root
        self.view = View3D(ctx)
        self.inspector_job, self.extract_job = BackgroundJob("inspect"), BackgroundJob("extract")
        self.textures = [ImageTexture(ctx) for _ in INSPECTOR_NAMES]
        self.colorbars = {name: ImageTexture(ctx, moderngl.LINEAR) for name in COLORMAPS}
        for name, texture in self.colorbars.items():
            texture.set(colorbar(name))
        self.exports: list[Path] = []
        self.stop_seconds: float | None = None
        self._dialog = None
        self._open(session)

    # --- sessions and runs
    def _open(self, session: Session) -> None:
        self.session = session
        self.state = UIState.for_config(session.preset, session.config)
        scene = session.scene
        self.view.set_scene(scene.cameras, scene.bounds, session.ground_truth)
        self._reset_run()

    def _reset_run(self) -> None:
        self.inspectors: list[Inspector] = []
        self.extraction: Extraction | None = None
        self.fscores: list[tuple[float, dict[int, float]]] = []
        self._applied_live: LiveSettings | None = None  # pushed to the next worker at once
        self._inspected = self._extracted = None
        self._last_inspect = self._last_extract = 0.0
        self._pending_exports: list[str] = []
        self._extract_asked = False

    def _start(self, fresh: bool) -> None:
        restart = self.state.restart
        config = restart.apply(self.session.base_config(restart.preset), self.state.live)
        self.session.start(restart.preset, config, fresh=fresh)
        self._reset_run()
        self.state.status = f"training into {self.session.run_dir}"

    @property
    def run_token(self) -> tuple[int, int]:
        """Identifies the current run across sessions (what job keys start with)."""
        return id(self.session), self.session.runs

    @property
    def worker(self) -> TrainingWorker | None:
        return self.session.worker

    @property
    def latest(self) -> Published | None:
        return None if self.worker is None else self.worker.latest

    # --- one frame
    def frame(self) -> list[Request]:
        """Update and draw everything; returns the requests only the window can act on."""
        window_requests = [r for r in self.state.take_requests() if not self._handle(r)]
        self._poll_dialog()
        self._sync_live()
        self._poll_jobs()
        latest = self.latest
        info = None if self.worker is None else self.worker.info
        self.view.sync(latest, None if info is None else info.raster, self.state.display, self.state.view,
                       None if self.extraction is None else self.extraction.curves)
        self._refresh_inspectors(latest)
        self._refresh_curves(latest)
        self._draw()
        return window_requests

    def _handle(self, request: Request) -> bool:
        """Act on a request; False for those the window acts on."""
        if request.name in WINDOW_REQUESTS:
            return False
        try:
            if request.name == "open":
                self._request_open(request.args.get("path"))
            elif request.name in ("start", "restart"):
                self._start(fresh=request.name == "restart")
            elif request.name in ("pause", "resume") and self.worker is not None:
                self.worker.update_controls(paused=request.name == "pause")
            elif request.name in ("extract", "export") and self.latest is None:
                self.state.status = "nothing to extract yet: start a run"
            elif request.name == "extract":
                self._extract_asked = True
            elif request.name == "export":
                self._pending_exports.append(request.args["format"])
            elif request.name == "snap":
                self.view.snap(self.state.view)
        except EdgeDogError as error:
            self.state.status = f"error: {error}"
        return True

    def _request_open(self, path: str | None) -> None:
        """Open `path`, or ask for a folder with the system's dialog when None."""
        if path is None:
            self._dialog = pfd.select_folder("Open a scene or run folder", str(self.session.opened))
            return
        session = Session.open(path, self.runs_root, self.state.restart.preset, self.session.overrides)
        self.session.stop()
        self._open(session)
        self.state.status = f"opened {session.opened}"

    def _poll_dialog(self) -> None:
        if self._dialog is not None and self._dialog.ready(0):
            path, self._dialog = self._dialog.result(), None
            if path:
                self.state.request("open", path=path)

    def _sync_live(self) -> None:
        """Send changed live settings to the worker (applied at its next step boundary)."""
        if self.worker is not None and self.state.live != self._applied_live:
            live = self.state.live
            self.worker.update_controls(keep_ratio=live.keep_ratio, weighting=live.weighting)
            self._applied_live = LiveSettings(live.keep_ratio, live.weighting)

    def _poll_jobs(self) -> None:
        done = self.inspector_job.poll()
        if done is not None and self._current(done):
            self._show_inspectors(done)
        done = self.extract_job.poll()
        if done is not None and self._current(done):
            self._take_extraction(done)

    def _current(self, done: Done) -> bool:
        """Whether a job's outcome belongs to the current run (not one replaced since)."""
        return done.key[:2] == self.run_token

    def _show_inspectors(self, done: Done) -> None:
        if done.error:
            self.state.status = f"inspectors: {done.error}"
            return
        self.inspectors = done.value
        for texture, inspector in zip(self.textures, self.inspectors):
            texture.set(inspector.rgba)

    def _take_extraction(self, done: Done) -> None:
        if done.error:
            self.state.status = f"extraction: {done.error}"
            return
        self.extraction = extraction = done.value
        if extraction.fscore is not None:
            self.fscores.append((extraction.elapsed, extraction.fscore))
        self.exports += extraction.written
        counts = f"{len(extraction.curves.lines)} lines, {len(extraction.curves.beziers)} Beziers"
        written = f"; wrote {', '.join(map(str, extraction.written))}" if extraction.written else ""
        self.state.status = f"curves at step {extraction.step}: {counts}{written}"

    def _refresh_inspectors(self, latest: Published | None) -> None:
        """Re-render the inspectors when the snapshot, the view or the weighting changed."""
        info = None if self.worker is None else self.worker.info
        scene = self.session.scene
        detector = info.detector if info else (scene.detectors[0] if scene.detectors else None)
        weighting = self.state.live.weighting
        shown = self.state.display.layers
        key = (*self.run_token, None if latest is None else latest.version, self.state.view, weighting,
               detector, tuple(sorted(name for name, on in shown.items() if on)))
        now = time.monotonic()
        if key == self._inspected or now - self._last_inspect < INSPECT_EVERY:
            return
        # The 2D render shows the layers the 3D view shows.
        snapshot = visible_subset(latest.snapshot, shown) if latest is not None and info is not None else None
        raster = None if info is None else info.raster
        view = min(self.state.view, len(scene) - 1)
        pixel_uncertainty = self.session.run_config.pixel_uncertainty
        if self.inspector_job.submit(key, lambda: inspect_view(snapshot, scene, view, detector, raster,
                                                               weighting, pixel_uncertainty)):
            self._inspected, self._last_inspect = key, now

    def _refresh_curves(self, latest: Published | None) -> None:
        """Extract when asked (exports), on the auto timer, and once for a finished run's result."""
        worker = self.worker
        if latest is None or worker is None or worker.info is None or self.extract_job.busy:
            return
        now = time.monotonic()
        asked = self._extract_asked or bool(self._pending_exports)
        timer = self.state.auto_extract and now - self._last_extract >= self.state.auto_extract_seconds
        key = (*self.run_token, latest.version)
        if not (asked or ((timer or worker.phase == FINISHED) and key != self._extracted)):
            return
        formats = self._pending_exports
        scene, info = self.session.scene, worker.info
        self.extract_job.submit(key, lambda: extract_snapshot(latest.snapshot, latest.elapsed, scene,
                                                              info.detector, info.run_dir, formats))
        self._pending_exports, self._extract_asked = [], False
        self._extracted, self._last_extract = key, now

    def _draw(self) -> None:
        areas = layout.studio_layout()
        controls_panel.draw(self, areas["controls"])
        view_panel.draw(self, areas["view"])
        plots_panel.draw(self, areas["plots"])
        inspector_panel.draw(self, areas["inspectors"])
        controls_panel.draw_status(self, areas["status"])

    # --- probes and closing
    def probe(self) -> dict:
        """Flat facts for the scripted driver and its report."""
        worker = self.worker
        facts = {"phase": None if worker is None else worker.phase, "runs": self.session.runs,
                 "steps": 0 if worker is None else worker.steps,
                 "steps_per_second": 0.0 if worker is None else worker.steps_per_second,
                 "error": None if worker is None else worker.error,
                 "version": None if self.latest is None else self.latest.version,
                 "splats_uploaded": self.view.splats.count, "splats_drawn": self.view.drawn,
                 "inspectors": len(self.inspectors), "exports": len(self.exports),
                 "export_paths": [str(path) for path in self.exports],
                 "fscores": len(self.fscores), "status": self.state.status,
                 "run_dir": None if worker is None or worker.info is None else str(worker.info.run_dir)}
        controls = None if worker is None else worker.trainer_controls()
        facts.update({f"controls.{name}": value for name, value in (controls or {}).items()})
        return facts

    def close(self) -> None:
        """Stop the run (within a second: it keeps its last checkpoint) and free GL objects."""
        started = time.perf_counter()
        self.session.stop(1.0)
        self.stop_seconds = time.perf_counter() - started
        self.view.release()
        for texture in [*self.textures, *self.colorbars.values()]:
            texture.release()
