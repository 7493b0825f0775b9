"""edgedog.renderer.gl: the ModernGL splat and line renderer of the studio.

DoG splats drawn as instanced quads that reproduce the training rasterizer's image, lines for
curves, points and camera frusta, an orbit view camera, and offscreen float render targets.
Nothing here holds GL state at module level; every object takes the context it lives in.
"""
