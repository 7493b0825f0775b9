"""Offscreen rendering of a mesh through EGL with ModernGL (no window, no display).

Two passes per view: grey shading that depends on the world normal only (a fixed lighting, see
LIGHTINGS) with multisampling, read back as RGBA with straight alpha on a transparent background
(as ABC-NEF's renders); then a single-sample pass that stores each pixel's camera depth and world
normal, for visibility and for tests against the geometry.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from edgedog.errors import EdgeDogError
from edgedog.renderer.gl.camera import gl_projection
from edgedog.renderer.gl.context import GLUnavailableError as ContextError
from edgedog.renderer.gl.context import offscreen_context
from edgedog.scenes.camera import Camera
from edgedog.synthetic.mesh import Mesh

ABC_NEF_IRRADIANCE = (0.746, 0.018, 0.012, 0.036, -0.037, -0.009, 0.003, 0.032, 0.040)
"""Grey level (0-1) as order-2 spherical harmonics of the world normal n = (x, y, z), on the basis
(1, x, y, z, xy, yz, xz, x^2 - y^2, 3z^2 - 1): least squares on ABC-NEF's renders of 00000006
(its mesh drawn with its 50 cameras, 200,000 interior pixels, the near-white inside of its hole
left out), residual 5.5 grey levels RMS. ABC-NEF's look: bright and soft, adjacent faces 10-40
grey levels apart."""
TWO_LIGHTS = ((0.4, 0.5, 0.75), (-0.6, -0.3, 0.2))
"""World directions towards the two lights of the built-in scenes' look (ambient 0.15, diffuse
0.75 / 1.3 each): faces 50-150 grey levels apart, for weight-free detectors."""
LIGHTINGS = ("abc-nef", "two-lights")
"""The looks `Renderer` draws; `edgedog make-scene` renders ABC-NEF's by default, the built-in scenes
the two lights."""
MAX_SAMPLES = 8  # multisampling; Mesa's software rasteriser offers 4
NEAR, FAR = 0.1, 100.0  # clipping depths, world units

VERTEX_SHADER = """
#version 330
uniform mat4 clip_from_world;
uniform mat4 camera_from_world;
in vec3 in_position;
in vec3 in_normal;
out vec3 normal;
out float depth;
void main() {
    gl_Position = clip_from_world * vec4(in_position, 1.0);
    depth = (camera_from_world * vec4(in_position, 1.0)).z;
    normal = in_normal;
}
"""
SHADED_FRAGMENTS = {
    "abc-nef": """
#version 330
uniform float irradiance[9];
in vec3 normal;
out vec4 color;
void main() {
    vec3 n = normalize(normal);
    float basis[9] = float[9](1.0, n.x, n.y, n.z, n.x * n.y, n.y * n.z, n.x * n.z, n.x * n.x - n.y * n.y,
                              3.0 * n.z * n.z - 1.0);
    float grey = 0.0;
    for (int i = 0; i < 9; i++) grey += irradiance[i] * basis[i];
    color = vec4(vec3(clamp(grey, 0.0, 1.0)), 1.0);
}
""",
    "two-lights": """
#version 330
uniform vec3 lights[2];
in vec3 normal;
out vec4 color;
void main() {
    vec3 n = normalize(normal);
    float light = max(dot(n, lights[0]), 0.0) + max(dot(n, lights[1]), 0.0);
    color = vec4(vec3(min(0.15 + 0.75 / 1.3 * light, 1.0)), 1.0);
}
"""}
GEOMETRY_FRAGMENT = """
#version 330
in vec3 normal;
in float depth;
out vec4 surface;
void main() {
    surface = vec4(depth, normalize(normal));
}
"""


class GLUnavailableError(EdgeDogError):
    """Offscreen OpenGL (EGL) cannot be started on this machine."""


@dataclass(frozen=True)
class Render:
    """One view of the mesh.

    Attributes:
        rgba: (H, W, 4) uint8, grey shading, straight (not premultiplied) alpha, 0 = background.
        depth: (H, W) float32 camera-space z of the surface at each pixel centre, 0 on background.
        normals: (H, W, 3) float32 world unit normal there, 0 on background.
    """

    rgba: np.ndarray
    depth: np.ndarray
    normals: np.ndarray


def create_context() -> moderngl.Context:
    """A headless ModernGL context through EGL, or GLUnavailableError (one line) saying why."""
    try:
        return offscreen_context()
    except ContextError as exc:
        raise GLUnavailableError(f"{' '.join(str(exc).split())}; install Mesa's EGL and GL drivers "
                                 "(Debian: libegl1 libgl1-mesa-dri)") from None


class Renderer:
    """Renders one mesh for cameras of one image size; a context manager that releases the
    GL context on exit.

    Args:
        mesh: the triangles to draw.
        width, height: image size in pixels.
        lighting: one of LIGHTINGS: "abc-nef" (ABC_NEF_IRRADIANCE) or "two-lights" (TWO_LIGHTS).
    """

    def __init__(self, mesh: Mesh, width: int, height: int, lighting: str = "two-lights"):
        if lighting not in LIGHTINGS:
            raise ValueError(f"lighting {lighting!r} is not one of {', '.join(LIGHTINGS)}")
        self.size = (width, height)
        self.ctx = create_context()
        try:
            self._build(mesh, lighting)
        except BaseException:
            self.ctx.release()
            raise

    def _build(self, mesh: Mesh, lighting: str) -> None:
        ctx = self.ctx
        vertices = np.concatenate([mesh.positions, mesh.normals], axis=2).astype("f4")  # (T, 3, 6)
        buffer = ctx.buffer(vertices.tobytes())
        self.programs = [ctx.program(vertex_shader=VERTEX_SHADER, fragment_shader=fragment)
                         for fragment in (SHADED_FRAGMENTS[lighting], GEOMETRY_FRAGMENT)]
        if lighting == "abc-nef":
            self.programs[0]["irradiance"].write(np.array(ABC_NEF_IRRADIANCE, "f4").tobytes())
        else:
            lights = np.array(TWO_LIGHTS)
            lights /= np.linalg.norm(lights, axis=1, keepdims=True)
            self.programs[0]["lights"].write(lights.astype("f4").tobytes())
        self.arrays = [ctx.vertex_array(program, [(buffer, "3f 3f", "in_position", "in_normal")])
                       for program in self.programs]
        samples = min(MAX_SAMPLES, ctx.max_samples)
        self.multisampled = ctx.framebuffer([ctx.renderbuffer(self.size, 4, samples=samples)],
                                            ctx.depth_renderbuffer(self.size, samples=samples))
        self.resolved = ctx.framebuffer([ctx.renderbuffer(self.size, 4)])
        self.geometry = ctx.framebuffer([ctx.renderbuffer(self.size, 4, dtype="f4")],
                                        ctx.depth_renderbuffer(self.size))

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    def release(self) -> None:
        self.ctx.release()

    def render(self, camera: Camera) -> Render:
        """Draw the mesh as `camera` sees it (the camera must have the renderer's size)."""
        if (camera.width, camera.height) != self.size:
            raise ValueError(f"camera is {camera.width}x{camera.height}, the renderer {self.size}")
        width, height = self.size
        clip = gl_projection(camera.K, width, height, NEAR, FAR) @ camera.w2c
        shading, geometry = self.programs
        for uniform, matrix in ((shading["clip_from_world"], clip), (geometry["clip_from_world"], clip),
                                (geometry["camera_from_world"], camera.w2c)):
            uniform.write(matrix.T.astype("f4").tobytes())  # column-major, as GLSL expects
        self.ctx.enable(moderngl.DEPTH_TEST)
        for framebuffer, array in zip((self.multisampled, self.geometry), self.arrays):
            framebuffer.use()
            framebuffer.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            array.render(moderngl.TRIANGLES)
        self.ctx.copy_framebuffer(self.resolved, self.multisampled)
        # OpenGL reads rows bottom-up and the projection puts image row 0 at the top: flip.
        premultiplied = np.frombuffer(self.resolved.read(components=4), np.uint8)
        surface = np.frombuffer(self.geometry.read(components=4, dtype="f4"), np.float32)
        premultiplied, surface = (a.reshape(height, width, 4)[::-1] for a in (premultiplied, surface))
        return Render(_unpremultiply(premultiplied), surface[..., 0].copy(), surface[..., 1:].copy())


def _unpremultiply(rgba: np.ndarray) -> np.ndarray:
    """Multisample resolution averages colour with the transparent background: divide it out."""
    alpha = rgba[..., 3:].astype(np.float32)
    rgb = np.where(alpha > 0, rgba[..., :3] * 255.0 / np.maximum(alpha, 1.0), 0.0)
    return np.concatenate([np.clip(np.round(rgb), 0, 255).astype(np.uint8), rgba[..., 3:]], axis=2)
