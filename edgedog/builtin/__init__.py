"""Built-in scenes with exact ground truth: procedural CAD parts rendered offscreen in the
ABC-NEF layout.

Modules, one job each: `features` (exact feature curves), `triangulate` (planar polygons with
holes), `prism` (extruded profiles: mesh and sharp edges), `shapes` (the catalogue of parts),
`cameras` (the ABC-NEF orbit), `render` (EGL/ModernGL renderer), `exact` (visibility and
exact edge maps), `degrade` (robustness degradations), `writer` (the scene folder).
"""
