"""GLSL sources of the GL renderer, shipped as package data (`edgedog.shaders`)."""
