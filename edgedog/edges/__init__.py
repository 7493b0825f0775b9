"""Pseudo-edge maps: 2D edge detectors (PiDiNet in torch, weight-free OpenCV ones) and the
per-scene cache of their maps."""
