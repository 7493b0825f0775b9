"""edgedog.app: EdgeDoG Studio, the desktop trainer and viewer (GLFW + ModernGL + imgui-bundle).

The window, its panels and the training thread live here; GL stays on the main thread and
the trainer publishes immutable snapshots that the window reads.
"""
