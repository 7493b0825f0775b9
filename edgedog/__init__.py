"""EdgeDoG: 3D edge reconstruction from posed images with Difference-of-Gaussians splatting.

Importing this package is cheap: it loads neither torch nor the C++ extension. Subpackages:
`edgedog.scenes` (datasets and cameras), `edgedog.groundtruth` and `edgedog.metrics`
(evaluation), `edgedog.renderer` (rasterizer and GL renderer), `edgedog.app` (the studio).
"""

__version__ = "0.2.0"
