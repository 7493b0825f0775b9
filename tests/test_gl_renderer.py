"""The ModernGL renderer (edgedog.renderer.gl), headless through EGL: splats against the training
rasterizer, lines, the view camera, and GL resource release.

GL tests skip, with the reason, only when EGL cannot create an OpenGL 3.3 context.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
import os
import subprocess
import sys
from pathlib import Path

import moderngl
import numpy as np
import pytest
import torch
from edgedog.renderer.config import ALPHA_MIN, RasterConfig
from edgedog.renderer.gl.camera import MIN_POLAR, ViewCamera, gl_projection
from edgedog.renderer.gl.context import GLUnavailableError, offscreen_context, window_context
from edgedog.renderer.gl.lines import LineRenderer, frustum_segments, polyline_segments
from edgedog.renderer.gl.programs import load_program, shader_source, with_defines
from edgedog.renderer.gl.splats import SplatRenderer
from edgedog.renderer.gl.target import OffscreenTarget
from edgedog.renderer.primitives import Primitives, RasterCamera
from edgedog.renderer.rasterize import rasterize

from edgedog.scenes.camera import Camera
from edgedog.train.trainer import Snapshot
from tests.helpers.raster_builders import random_primitives

pytestmark = pytest.mark.gl

WIDTH, HEIGHT = 200, 150


@pytest.fixture
def ctx():
    # One per test: moderngl draws with whichever context is current, and creating one makes it so.
    try:
        context = offscreen_context()
    except GLUnavailableError as error:
        pytest.skip(f"no headless OpenGL: {error}")
    yield context
    context.release()


@pytest.fixture
def target(ctx):
    target = OffscreenTarget(ctx, WIDTH, HEIGHT)
    yield target
    target.release()


@pytest.fixture
def splats(ctx):
    renderer = SplatRenderer(ctx)
    yield renderer
    renderer.release()


def view(width=WIDTH, height=HEIGHT) -> Camera:
    """Looks at the random primitives' centre (0.5, 0.5, 0.5) from 1.8 away, world -y up."""
    return ViewCamera.looking_at([0.5, 0.5, -1.3], [0.5, 0.5, 0.5], [0, -1, 0], width, height,
                                 fov_y=np.radians(45)).camera()


def snapshot(prims: Primitives) -> Snapshot:
    """What the trainer publishes for these primitives, as read-only arrays."""
    with torch.no_grad():
        arrays = [prims.means, prims.log_scales.exp(), prims.quats, torch.sigmoid(prims.opacity_logits),
                  prims.k_raw]
    arrays = [x.numpy().copy() for x in arrays]
    for array in arrays:
        array.flags.writeable = False
    return Snapshot(0, 0, 0.0, *arrays, pruned_positions=np.zeros((0, 3), np.float32))


def gl_render(target, splats, snap, camera, config=RasterConfig(), colors=None, version=0) -> np.ndarray:
    splats.upload(snap, version, config)
    if colors is not None:
        splats.set_colors(colors)
    target.use()
    target.clear()
    splats.render(camera)
    return target.read()


# --- splats against the training rasterizer --------------------------------------------------

@pytest.mark.parametrize("kernel,k_activation", [("dog", "sigmoid"), ("dog", "exp"), ("gaussian", "sigmoid")])
@pytest.mark.parametrize("n,spread", [(300, 0.3), (400, 0.08)], ids=["sparse", "dense"])
def test_splats_match_the_training_rasterizer(target, splats, kernel, k_activation, n, spread):
    prims = random_primitives(n=n, spread=spread, channels=3, dtype=torch.float32)
    config = RasterConfig(kernel=kernel, k_activation=k_activation)
    camera = view()
    expected = rasterize(prims, RasterCamera.from_camera(camera), config)
    reference = torch.cat([expected.image, expected.alpha[..., None]], -1).detach().numpy()

    image = gl_render(target, splats, snapshot(prims), camera, config, prims.colors.numpy())

    error = np.abs(image - reference)
    psnr = 10 * np.log10(1 / np.mean(error**2))
    metrics = f"max {error.max():.2e}, mean {error.mean():.2e}, PSNR {psnr:.1f} dB"
    assert (reference[..., 3] > 0).mean() > 0.04, "the primitives should cover the view"
    # Both evaluate the same float32 maths, so pixels agree to rounding except in two places.
    # Where u sits on the support bound u_s, alpha ~ ALPHA_MIN, and one side may keep what the
    # other skips: at most ALPHA_MIN of difference, and rare. Where the rasterizer stopped early
    # (the next primitive would take T below 0.99e-4, so T < 1e-2 there), GL adds what is left: < T.
    opaque = reference[..., 3] > 1 - 1e-2
    assert error.mean() < 1e-5, metrics
    assert np.mean(error < 1e-4) > 0.999, metrics
    assert error[~opaque].max() < ALPHA_MIN, metrics
    assert error.max() < 1e-2, metrics


def test_grey_render_is_the_training_render_of_colour_one(target, splats):
    prims = random_primitives(n=200, channels=1, dtype=torch.float32)
    prims.colors = torch.ones_like(prims.colors)
    camera = view()
    expected = rasterize(prims, RasterCamera.from_camera(camera)).image[..., 0].detach().numpy()

    image = gl_render(target, splats, snapshot(prims), camera)

    np.testing.assert_allclose(image[..., :3], np.repeat(expected[..., None], 3, -1), atol=ALPHA_MIN)
    np.testing.assert_allclose(image[..., 0], image[..., 3])  # colour 1: intensity = alpha
    assert np.abs(image[..., 0] - expected).mean() < 1e-5


def test_upload_only_when_the_version_or_the_config_changes(splats):
    snap = snapshot(random_primitives(n=20, dtype=torch.float32))
    assert splats.upload(snap, version=3)
    assert not splats.upload(snap, version=3)
    assert splats.upload(snap, version=4)
    assert splats.upload(snap, version=4, config=RasterConfig(kernel="gaussian"))
    assert not splats.upload(snap, version=4, config=RasterConfig(kernel="gaussian"))
    assert splats.count == 20


def test_colours_change_without_a_new_upload(target, splats):
    prims = random_primitives(n=100, dtype=torch.float32)
    snap, camera = snapshot(prims), view()
    grey = gl_render(target, splats, snap, camera)

    red = gl_render(target, splats, snap, camera, colors=np.tile([1.0, 0.0, 0.0], (100, 1)))

    np.testing.assert_array_equal(red[..., 0], grey[..., 0])
    assert not red[..., 1:3].any()
    with pytest.raises(ValueError):
        splats.set_colors(np.ones((99, 3)))


def test_primitives_behind_at_or_just_before_the_camera_plane_are_not_drawn(target, splats):
    # The camera sits at the origin looking down +z; each point would project into the image
    # (x/z, y/z small) if its depth sign or size were ignored.
    means = np.array([[0.02, 0.01, -1.0], [0.0, 0.0, 0.0], [0.001, 0.0, 0.005], [0.05, 0.0, -0.3]])
    n = len(means)
    snap = Snapshot(0, 0, 0.0, means.astype(np.float32), np.full((n, 3), 0.2, np.float32),
                    np.tile(np.float32([1, 0, 0, 0]), (n, 1)), np.full(n, 0.9, np.float32),
                    np.zeros((n, 2), np.float32), np.zeros((0, 3), np.float32))
    K = np.array([[100.0, 0, 49.5], [0, 100.0, 49.5], [0, 0, 1]])
    camera = Camera(K=K, w2c=np.eye(4), width=100, height=100)
    prims = Primitives(torch.from_numpy(snap.means), torch.from_numpy(np.log(snap.scales)),
                       torch.from_numpy(snap.quats), torch.logit(torch.from_numpy(snap.opacity)),
                       torch.from_numpy(snap.k_raw), torch.ones(n, 1))
    assert not rasterize(prims, RasterCamera.from_camera(camera)).alpha.any()

    box = OffscreenTarget(splats.ctx, 100, 100)
    try:
        image = gl_render(box, splats, snap, camera)
        assert splats.render(camera) == 0
        snap.means[0, 2] = 1.0  # the first one in front of the camera instead: drawn
        in_front = gl_render(box, splats, snap, camera, version=1)
        assert splats.render(camera) == 1
    finally:
        box.release()
    assert not image.any()
    assert in_front[..., 3].max() > 0.5


def test_non_finite_primitives_are_skipped_without_crashing(target, splats):
    prims = random_primitives(n=60, channels=3, dtype=torch.float32)
    snap, camera = snapshot(prims), view()
    colors = prims.colors.numpy()
    clean = gl_render(target, splats, snap, camera, colors=colors)

    bad = {name: np.array(getattr(snap, name)) for name in ("means", "scales", "quats", "opacity", "k_raw")}
    extra = {"means": [np.nan, 0.5, 0.5], "scales": [0.02, np.inf, 0.01], "quats": [np.nan, 0, 0, 1],
             "opacity": np.nan, "k_raw": [np.nan, 0.0]}
    for name, value in extra.items():  # one more primitive per field, non-finite there only
        row = {k: v[:1].copy() for k, v in bad.items()}
        row[name][0] = value
        bad = {k: np.concatenate([bad[k], row[k]]) for k in bad}
    snap_bad = Snapshot(0, 0, 0.0, pruned_positions=np.zeros((0, 3)), **bad)

    image = gl_render(target, splats, snap_bad, camera, colors=np.concatenate([colors, np.ones((5, 3))]),
                      version=1)

    assert np.isfinite(image).all()
    np.testing.assert_array_equal(image, clean)


def test_nothing_uploaded_or_nothing_visible_draws_nothing(target, splats):
    camera = view()
    assert splats.render(camera) == 0
    shapes = ((0, 3), (0, 3), (0, 4), (0,), (0, 2))
    empty = Snapshot(0, 0, 0.0, *(np.zeros(shape, np.float32) for shape in shapes), np.zeros((0, 3)))
    assert not gl_render(target, splats, empty, camera).any()
    splats.set_colors(np.zeros((0, 3)))


def test_upload_rejects_wrong_shapes(splats):
    snap = snapshot(random_primitives(n=5, dtype=torch.float32))
    with pytest.raises(ValueError, match="k_raw"):
        splats.upload(Snapshot(0, 0, 0.0, snap.means, snap.scales, snap.quats, snap.opacity,
                               snap.k_raw[:, :1], snap.pruned_positions), version=0)


def render_in_a_window() -> None:
    """Draws splats into a hidden GLFW window's default framebuffer and checks the pixels (needs
    an X display; run in its own process, since a GLX context does not mix with EGL ones)."""
    import glfw

    assert glfw.init(), "GLFW cannot open the display"
    try:
        for hint, value in ((glfw.CONTEXT_VERSION_MAJOR, 3), (glfw.CONTEXT_VERSION_MINOR, 3),
                            (glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE), (glfw.VISIBLE, False)):
            glfw.window_hint(hint, value)
        window = glfw.create_window(WIDTH, HEIGHT, "test", None, None)
        assert window, "no OpenGL 3.3 core window"
        glfw.make_context_current(window)
        ctx = window_context()
        prims = random_primitives(n=300, channels=3, dtype=torch.float32)
        camera = view()
        splats = SplatRenderer(ctx)
        splats.upload(snapshot(prims), 0)
        splats.set_colors(prims.colors.numpy())
        ctx.screen.use()
        ctx.screen.clear(0.0, 0.0, 0.0, 0.0)
        splats.render(camera)
        pixels = np.frombuffer(ctx.screen.read(components=4), np.uint8).reshape(HEIGHT, WIDTH, 4)[::-1] / 255
        splats.release()
        ctx.release()
    finally:
        glfw.terminate()
    expected = rasterize(prims, RasterCamera.from_camera(camera))
    reference = torch.cat([expected.image, expected.alpha[..., None]], -1).detach().numpy()
    error = np.abs(pixels - reference)
    # 8-bit colour: every blend rounds to 1/255; a misplaced or flipped image would be far off.
    assert error.mean() < 1 / 255 and error.max() < 8 / 255, f"max {error.max():.4f}, mean {error.mean():.5f}"


@pytest.mark.xvfb
def test_splats_draw_into_a_window_framebuffer(xvfb_display):
    code = "import tests.test_gl_renderer as t; t.render_in_a_window()"
    result = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).parents[1],
                            env={**os.environ, "DISPLAY": xvfb_display}, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]


# --- shaders ---------------------------------------------------------------------------------

def test_every_shader_program_compiles_and_links(ctx):
    splats, lines = SplatRenderer(ctx), LineRenderer(ctx)
    try:
        assert {"in_index", "u_params", "u_rotation", "u_eps2d"} <= set(splats.program)
        assert {"in_position", "in_color", "u_view_projection", "u_point_size"} <= set(lines.program)
        assert splats.program.glo > 0 and lines.program.glo > 0
    finally:
        splats.release()
        lines.release()


def test_defines_follow_the_version_line_and_a_failure_names_the_program(ctx):
    source = with_defines(shader_source("splats.frag"), {"ALPHA_MAX": 0.99})
    assert source.splitlines()[:2] == ["#version 330 core", "#define ALPHA_MAX 0.99"]
    with pytest.raises(moderngl.Error, match="'splats'"):
        load_program(ctx, "splats", {})  # FRUSTUM_SLACK etc. undefined


def test_shaders_ship_as_package_data(tmp_path):
    # What a wheel would hold (the packages and package data of pyproject.toml), imported in
    # place of the source tree.
    repo = Path(__file__).resolve().parents[1]
    build = subprocess.run([sys.executable, "-c", "from setuptools import setup; setup()", "-q", "build_py",
                            "--build-lib", str(tmp_path)], cwd=repo, capture_output=True, text=True)
    assert build.returncode == 0, build.stderr[-2000:]
    code = ("import edgedog.shaders as s, edgedog.renderer.gl.programs as p; print(s.__file__);"
            "print(p.shader_source('splats.frag').splitlines()[0])")
    load = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(tmp_path)})
    assert load.returncode == 0, load.stderr[-2000:]
    location, first_line = load.stdout.splitlines()
    assert Path(location).parent == tmp_path / "edgedog" / "shaders"
    assert first_line == "#version 330 core"
    def glsl(folder):
        return {f.name for f in folder.iterdir() if f.suffix in (".vert", ".frag")}

    assert glsl(tmp_path / "edgedog" / "shaders") == glsl(repo / "shaders") == {
        "splats.vert", "splats.frag", "lines.vert", "lines.frag"}


# --- lines -----------------------------------------------------------------------------------

def test_points_and_segments_land_on_their_projected_pixels(ctx, target):
    camera = view()
    lines = LineRenderer(ctx)
    try:
        points = np.array([[0.51, 0.52, 0.5], [0.6, 0.45, 0.4], [0.3, 0.6, 0.7], [0.5, 0.5, -2.0]])
        lines.set_points("gt", points, (0.0, 1.0, 0.0), size=1.0)
        target.use()
        target.clear()
        lines.render(camera)
        image = target.read()
        pixels, inside = camera.pixels(points)
        assert inside.tolist() == [True, True, True, False]  # the last one is behind the camera
        hit = np.argwhere(image[..., 1] > 0)
        assert sorted(map(tuple, hit)) == sorted((y, x) for x, y in pixels[inside])

        lines.remove("gt")
        lines.set_segments("curve", polyline_segments([points[:2]]), (1.0, 0.0, 0.0, 0.5))
        target.clear()
        lines.render(camera)
        image = target.read()
        drawn = np.argwhere(image[..., 3] > 0)
        assert len(drawn) >= np.abs(pixels[0] - pixels[1]).max() - 1  # a connected line
        np.testing.assert_allclose(image[image[..., 3] > 0], [[0.5, 0, 0, 0.5]] * len(drawn))
    finally:
        lines.release()


def test_segments_through_the_camera_are_clipped_and_non_finite_ones_dropped(ctx, target):
    camera = view()
    lines = LineRenderer(ctx)
    try:
        behind_to_front = [[0.3, 0.5, -3.0], [0.5, 0.5, 0.5]]  # crosses the camera plane
        not_finite = [[np.nan, 0, 0], [0.5, 0.5, 0.5]]
        lines.set_segments("s", np.array([behind_to_front, not_finite]), (1.0, 1.0, 1.0))
        lines.set_points("p", np.full((3, 3), np.inf), (1.0, 1.0, 1.0))
        target.use()
        target.clear()
        lines.render(camera)
        image = target.read()
        assert np.isfinite(image).all()
        assert image[..., 3].any()
    finally:
        lines.release()


def test_polyline_segments_join_consecutive_points():
    segments = polyline_segments([np.arange(9.0).reshape(3, 3), np.zeros((1, 3)), np.ones((2, 3))])
    assert segments.shape == (3, 2, 3)
    np.testing.assert_array_equal(segments[1], [[3, 4, 5], [6, 7, 8]])
    assert polyline_segments([]).shape == (0, 2, 3)


def test_frustum_corners_project_onto_the_image_corners():
    camera = view(64, 48)
    segments = frustum_segments([camera, camera], depth=0.25)
    assert segments.shape == (16, 2, 3)
    np.testing.assert_allclose(segments[:4, 0], np.tile(camera.center, (4, 1)))
    uv, depth = camera.project(segments[:4, 1])
    np.testing.assert_allclose(uv, [[-0.5, -0.5], [63.5, -0.5], [63.5, 47.5], [-0.5, 47.5]], atol=1e-9)
    np.testing.assert_allclose(depth, 0.25)


# --- view camera -----------------------------------------------------------------------------

def test_gl_projection_puts_points_on_their_pinhole_pixels():
    camera = view(120, 90)
    points = np.random.default_rng(0).uniform(0.2, 0.8, (50, 3))
    clip = np.c_[points, np.ones(50)] @ (gl_projection(camera.K, 120, 90, 0.1, 10.0) @ camera.w2c).T
    ndc = clip[:, :3] / clip[:, 3:]
    pixels = np.c_[(ndc[:, 0] + 1) * 60 - 0.5, (1 - ndc[:, 1]) * 45 - 0.5]  # row 0 at the top
    uv, depth = camera.project(points)
    np.testing.assert_allclose(pixels, uv, atol=1e-9)
    assert np.all(np.abs(ndc[:, 2]) < 1)
    near_far = np.array([[0, 0, 0.1, 1], [0, 0, 10.0, 1]]) @ gl_projection(camera.K, 120, 90, 0.1, 10.0).T
    np.testing.assert_allclose(near_far[:, 2] / near_far[:, 3], [-1, 1])


def test_looking_at_centres_the_target_with_up_upwards():
    viewer = ViewCamera.looking_at([1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [0, 0, 1], 80, 60)
    camera = viewer.camera()
    uv, depth = camera.project(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.1]]))
    np.testing.assert_allclose(uv[0], [39.5, 29.5])
    assert uv[1, 1] < uv[0, 1]  # +z (up) goes up the image
    np.testing.assert_allclose(depth[0], np.sqrt(14))
    np.testing.assert_allclose(camera.R @ camera.R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(camera.R) == pytest.approx(1)
    with pytest.raises(ValueError, match="parallel"):
        ViewCamera.looking_at([0.0, 0, 2], [0, 0, 0], [0, 0, 1], 80, 60)


def test_snap_to_a_training_camera_gives_that_view():
    training = view(160, 120)
    viewer = ViewCamera.looking_at([3.0, 0, 0], [0, 0, 0], [0, 0, 1], 160, 120)
    viewer.snap_to(training, distance=1.5)
    snapped = viewer.camera()
    np.testing.assert_allclose(snapped.K, training.K)
    np.testing.assert_allclose(snapped.w2c, training.w2c, atol=1e-12)
    np.testing.assert_allclose(viewer.target, training.center + 1.5 * training.forward)

    # A wider viewport shows the whole training image, centred, with square pixels.
    viewer.resize(320, 120)
    viewer.snap_to(training)
    corners, _ = viewer.camera().project(frustum_segments([training], 1.0)[:4, 1])
    np.testing.assert_allclose(corners, [[79.5, -0.5], [239.5, -0.5], [239.5, 119.5], [79.5, 119.5]],
                               atol=1e-9)


def test_orbit_pan_and_zoom_move_the_camera_as_documented():
    viewer = ViewCamera.looking_at([0.0, -2.0, 0.0], [0, 0, 0], [0, 0, 1], 100, 100)
    viewer.orbit(np.pi / 2, 0.0)  # a quarter turn about +z: from -y to +x
    np.testing.assert_allclose(viewer.center, [2, 0, 0], atol=1e-12)
    np.testing.assert_allclose(viewer.target, 0, atol=1e-12)

    viewer.orbit(0.0, -0.3)  # the view direction tilts down: the camera rises
    np.testing.assert_allclose(viewer.center, [2 * np.cos(0.3), 0, 2 * np.sin(0.3)], atol=1e-12)
    viewer.orbit(0.0, -10.0)  # stops short of looking straight down
    polar = np.arccos(viewer.rotation[2] @ viewer.up)
    np.testing.assert_allclose(polar, np.pi - MIN_POLAR)

    before = viewer.camera()
    viewer.pan(10.0, 0.0)  # the target moves 10 pixels to the right in the image
    uv, _ = viewer.camera().project(np.array([[0.0, 0, 0]]))
    old_uv, _ = before.project(np.array([[0.0, 0, 0]]))
    np.testing.assert_allclose(uv - old_uv, [[10.0, 0.0]], atol=1e-9)

    viewer.zoom(0.5)
    assert viewer.distance == pytest.approx(1.0)
    with pytest.raises(ValueError):
        viewer.zoom(0.0)


# --- resources -------------------------------------------------------------------------------

GL_IS = {moderngl.Buffer: "glIsBuffer", moderngl.Texture: "glIsTexture", moderngl.TextureArray: "glIsTexture",
         moderngl.Program: "glIsProgram", moderngl.VertexArray: "glIsVertexArray",
         moderngl.Framebuffer: "glIsFramebuffer", moderngl.Renderbuffer: "glIsRenderbuffer"}


def live_gl_names(objects) -> list:
    """The (function, name) pairs among `objects` that the current context still knows."""
    library = ctypes.util.find_library("OpenGL")
    if library is None:
        pytest.skip("libOpenGL (glvnd) is not available to query object names")
    gl = ctypes.CDLL(library)
    names = []
    for obj in objects:
        function = getattr(gl, GL_IS[type(obj)])
        function.restype = ctypes.c_ubyte
        if function(obj.glo):
            names.append((GL_IS[type(obj)], obj.glo))
    return names


def draw_everything(ctx, width=64, height=48):
    """Every renderer and target, used once; returns them unreleased."""
    prims = random_primitives(n=50, dtype=torch.float32)
    camera = view(width, height)
    target, splats, lines = OffscreenTarget(ctx, width, height), SplatRenderer(ctx), LineRenderer(ctx)
    splats.upload(snapshot(prims), 0)
    splats.set_colors(np.ones(50))
    lines.set_segments("frusta", frustum_segments([camera], 0.2), (1.0, 0.0, 0.0))
    lines.set_points("gt", prims.means.numpy(), (0.0, 1.0, 0.0))
    target.use()
    target.clear()
    splats.render(camera)
    lines.render(camera)
    target.read()
    return target, splats, lines


def test_release_deletes_every_gl_object(ctx):
    def gl_objects():
        gc.collect()
        return [o for o in gc.get_objects() if type(o) in GL_IS]

    before = gl_objects()  # kept alive, so that no new object reuses one of their ids
    first = draw_everything(ctx)
    created = [o for o in gl_objects() if all(o is not old for old in before)]
    assert {type(o) for o in created} == set(GL_IS)
    assert len(live_gl_names(created)) == len(created)
    for obj in first:
        obj.release()
    # A program stays alive while it is current, so draw with fresh ones before checking.
    for obj in draw_everything(ctx):
        obj.release()
    assert live_gl_names(created) == []


def test_a_hundred_context_cycles_do_not_grow_memory():
    def rss() -> int:
        with open("/proc/self/statm") as statm:
            return int(statm.read().split()[1]) * 4096

    def cycle():
        try:
            context = offscreen_context()
        except GLUnavailableError as error:
            pytest.skip(f"no headless OpenGL: {error}")
        for obj in draw_everything(context, 256, 192):
            obj.release()
        context.release()

    for _ in range(10):  # warm up Mesa's shader cache and the allocator
        cycle()
    start = rss()
    for _ in range(100):
        cycle()
    growth = (rss() - start) / 100
    # moderngl 5.13 keeps ~40 KB of Python ints per context it creates (its GL function table);
    # a context left alive costs ~5 MB, a leaked 256 x 192 target ~1 MB.
    assert growth < 256 * 1024, f"{growth / 1024:.0f} KiB per open/close cycle"
