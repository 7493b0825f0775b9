"""Curve extraction: a trained run's primitives -> filtered edge points -> lines and Béziers.

Modules, in pipeline order: `primitives` (read primitives.ply), `filtering` (opacity,
projection, statistical outliers, silhouette), `grouping` (points -> vertex chains),
`topology` (split at corners and junctions), `fitting` (RANSAC lines, least-squares
Béziers), `junctions` (merge collinear lines, snap ends). `extract` is the public API
(`extract_curves`, `extract_run`); `config` holds its settings.
"""
