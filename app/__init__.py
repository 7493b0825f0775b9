"""edgedog.app: EdgeDoG Studio, the desktop trainer and viewer (GLFW + ModernGL + imgui-bundle).

GL and GLFW stay on the main thread; the trainer runs in a worker thread and publishes
immutable snapshots that the window reads.

- window.py, display.py, redraw.py: GLFW, the GL context, imgui's backends and the frame loop,
  which draws a frame only when it differs from the one shown.
- studio.py: one frame: requests, live controls, 3D view, inspectors, curves, panels.
- state.py: what the panels edit; script.py: a scripted driver feeding the same state.
- session.py, worker.py: the scene, its run folders, and the training thread.
- photos.py, sfm_job.py, sfm_progress.py: a folder of photos opened: the offer of structure from
  motion, `edgedog sfm` in a child process that Cancel ends at once, and its progress by stage.
- view3d.py, points_view.py, textures.py: GL drawing (points_view.py: a scene's sparse SfM
  points); inspection.py, extraction.py, jobs.py: work done off the UI thread; colors.py,
  layers.py, rates.py: colour maps, the layer list and the readouts' moving rates.
- layout.py and *_panel.py: the panels.
"""

MIN_SIZE = (640, 480)
"""The smallest window (screen coordinates) the layout serves; here, so that the command line
checks --size without loading imgui."""
STUDIO_PRESET = "quick"
"""The preset of the studio's new runs (`edgedog studio --preset`): the best F-score in about a
minute of training on a laptop's CPU (README's results), where `edgedog train` defaults to `full`."""
