"""Synthetic CAD parts with exact feature curves, rendered offscreen.

Modules, one job each: `features` (exact feature curves), `triangulate` (planar polygons with
holes), `prism` (extruded profiles: mesh and sharp edges), `shapes` (the catalogue of parts),
`cameras` (the ABC-NEF orbit), `render` (EGL/ModernGL renderer), `exact` (visibility and
exact edge maps), `degrade` (robustness degradations). `edgedog.builtin` writes scenes of them.
"""
