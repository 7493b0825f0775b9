"""Synthetic CAD parts with exact feature curves, rendered offscreen.

The solids come from the CAD kernel (OpenCascade through build123d). Modules, one job each:
`designs` (the built-in parts, modelled), `shapes` (their catalogue and the Part they become),
`brep` (a solid as a normalised Part), `tessellate` (the kernel's triangulation as a `mesh`),
`sharp` (sharp edges as exact curves: ground truth), `features` (those curves and their
sampling), `cad_file` (a user's STEP or BREP file, checked), `abc_file` (an ABC object's mesh
and features file), `cameras` (the ABC-NEF orbit),
`render` (EGL/ModernGL renderer), `exact` (visibility and exact edge maps), `degrade`
(robustness degradations). `edgedog.builtin` writes scenes of them.
"""
