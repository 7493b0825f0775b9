"""Curve extraction: a trained run's primitives -> filtered edge points -> lines and Béziers.

The input is `edgedog.primitives.EdgePrimitives` (from a snapshot in memory or primitives.ply).
Modules, in pipeline order: `filtering` (opacity, projection, statistical outliers,
silhouette), `grouping` (points -> vertex chains), `topology` (split at corners and
junctions), `fitting` (RANSAC lines, least-squares Béziers), `junctions` (merge collinear
lines, snap ends). `extract` is the public API (`extract_curves`, `extract_primitives`,
`extract_run`); `config` holds its settings.
"""
