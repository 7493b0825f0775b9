"""Rendering the built-in parts: ground truth on the renders' geometric edges, the exact box
scene, the default scene, and a clear error without EGL."""

from __future__ import annotations

import moderngl
import numpy as np
import pytest

from edgedog.builtin import scene as builtin_scene
from edgedog.cli import main
from edgedog.groundtruth import ground_truth_for
from edgedog.scenes import load_scene
from edgedog.scenes.camera import Camera, rigid_inverse
from edgedog.synthetic.cameras import orbit_cameras
from edgedog.synthetic.exact import visible
from edgedog.synthetic.render import GLUnavailableError, Renderer
from edgedog.synthetic.shapes import SHAPES, make_part


def geometric_edges(render, camera) -> np.ndarray:
    """(H, W) bool: both pixels of every neighbouring pair across a crease (normals > 30 degrees
    apart), a depth jump or the object's outline: the pixels within one of a discontinuity."""
    depth, normals = render.depth.astype(np.float64), render.normals.astype(np.float64)
    pixel = depth / camera.K[0, 0]  # world size of a pixel at that depth
    edges = np.zeros(depth.shape, bool)
    for axis in (0, 1):
        d0, d1 = depth, np.roll(depth, -1, axis)
        crease = np.einsum("ijk,ijk->ij", normals, np.roll(normals, -1, axis)) < np.cos(np.radians(30))
        jump = (np.abs(d1 - d0) > 4 * np.maximum(pixel, np.roll(pixel, -1, axis))) | ((d0 > 0) != (d1 > 0))
        edges |= crease | jump
        edges |= np.roll(crease | jump, 1, axis)
    return edges


@pytest.mark.gl
@pytest.mark.parametrize("name", SHAPES)
def test_visible_ground_truth_lands_on_the_renders_geometric_edges(name):
    part = make_part(name, 1)
    points = part.ground_truth()
    cameras = orbit_cameras(4, 400)  # 1 px is ~7 mm on the object
    with Renderer(part.mesh, 400, 400) as renderer:
        for camera in cameras:
            render = renderer.render(camera)
            shown = visible(points, camera, render)
            assert 0.15 < shown.mean() < 0.95  # some curves face away or hide behind others
            edges = geometric_edges(render, camera)
            assert edges[render.depth > 0].mean() < 0.5  # the edge mask is no blanket
            on_edges = []
            for shift in (0.0, 0.021):  # the curves, then a copy 3 px off: the test can tell
                pixels, inside = camera.pixels(points[shown] + shift / np.sqrt(3))
                assert inside.all()
                on_edges.append(edges[pixels[:, 1], pixels[:, 0]].mean())
            assert on_edges[0] > 0.98 and on_edges[1] < 0.9, (name, on_edges)
            # The renders are grey RGBA on a transparent background, opaque where the mesh is.
            alpha = render.rgba[..., 3]
            assert alpha[0, 0] == 0 and np.all(alpha[render.depth > 0] > 0)
            assert (alpha == 255).sum() >= 0.95 * (render.depth > 0).sum()


@pytest.mark.gl
def test_hidden_points_are_not_visible():
    part = make_part("boss", 0)
    c2w = np.eye(4)
    c2w[:3, :3] = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]  # looking straight down -Z, image x along +X
    c2w[:3, 3] = [0.5, 0.5, 4.5]
    camera = Camera(orbit_cameras(1, 200)[0].K, rigid_inverse(c2w), 200, 200)
    with Renderer(part.mesh, 200, 200) as renderer:
        render = renderer.render(camera)
    top, bottom = part.mesh.positions[..., 2].max(), part.mesh.positions[..., 2].min()
    ring = [c for c in part.curves if np.isclose(c.at(np.zeros(1))[0, 2], top)]
    floor = np.concatenate([c.at(np.linspace(0, 1, 50)) for c in part.curves
                            if np.allclose(c.at(np.array([0.0, 1.0]))[:, 2], bottom)])
    assert visible(ring[0].at(np.linspace(0, 1, 50)), camera, render).all()
    assert not visible(floor, camera, render).any()  # the bottom outline is under the base


def test_the_exact_box_scene_loads_as_an_abc_nef_scene(builtin_scene_dir):
    scene = load_scene(builtin_scene_dir)
    assert scene.format == "nerf" and len(scene) == 50 and scene.detectors == ["exact"]
    points = ground_truth_for(scene.root).load()
    # 12 box edges, perimeter 4 * (0.6 + 0.4 + 0.3) = 5.2 units sampled every ~5 mm.
    assert 1000 <= len(points) <= 1040 and points.min() >= 0 and points.max() <= 1
    np.testing.assert_allclose(points, builtin_scene.ground_truth_points())
    for i in range(0, len(scene), 10):
        camera, edges, mask = scene.camera(i), scene.load_edge_map(i), scene.load_mask(i)
        pixels, inside = camera.pixels(points)
        assert inside.all() and mask[pixels[:, 1], pixels[:, 0]].mean() > 0.5
        values = edges[pixels[:, 1], pixels[:, 0]]
        # The box edges that the camera sees are drawn, hidden ones are not.
        assert values.mean() > 10 * edges.mean()
        assert 0.4 < (values > 0.5).mean() < 0.95


@pytest.mark.gl
def test_render_view_sees_the_faces_that_face_the_camera():
    camera = orbit_cameras(50, 200)[0]  # the first view sits near the +Z pole, looking down
    rgba, edges = builtin_scene.render_view(camera)
    centre_top = np.array([0.5, 0.5, builtin_scene.CORNERS[:, 2].max()])
    uv, _ = camera.project(centre_top[None])
    x, y = np.round(uv[0]).astype(int)
    assert rgba[y, x, 3] == 255 and edges[y, x] == 0  # inside the top face, away from edges
    assert rgba[0, 0, 3] == 0 and edges.max() == 255
    assert len(builtin_scene.EDGES) == 12


@pytest.mark.gl
def test_the_default_scene_is_generated_once_in_the_cache(tmp_path, monkeypatch):
    # Canny maps even where PiDiNet weights are configured (these would not even load).
    monkeypatch.setenv("EDGEDOG_PIDINET", str(tmp_path / "no-weights-here"))
    monkeypatch.setattr(builtin_scene, "DEFAULT_VIEWS", 3)
    monkeypatch.setattr(builtin_scene, "DEFAULT_SIZE", 96)
    # An older version cached the scene as scenes/boss, with PiDiNet maps where weights were set.
    stale = tmp_path / "scenes" / builtin_scene.DEFAULT_SHAPE
    stale.mkdir(parents=True)
    (stale / "transforms_train.json").write_text("{}")
    folder = builtin_scene.builtin_scene_path(tmp_path)
    assert folder == tmp_path / "scenes" / "boss-canny"
    assert sorted(p.name for p in folder.parent.iterdir()) == ["boss", "boss-canny"]  # no partial folder
    scene = load_scene(folder)
    assert len(scene) == 3 and scene.detectors == ["canny"] and ground_truth_for(scene.root) is not None
    stamp = (folder / "transforms_train.json").stat().st_mtime_ns
    assert builtin_scene.builtin_scene_path(tmp_path) == folder
    assert (folder / "transforms_train.json").stat().st_mtime_ns == stamp


def test_without_egl_the_error_is_one_line(monkeypatch, tmp_path, capsys):
    def no_egl(*args, **kwargs):
        raise Exception("libEGL.so.1: cannot open shared object file:\n No such file or directory")

    monkeypatch.setattr(moderngl, "create_standalone_context", no_egl)
    with pytest.raises(GLUnavailableError, match="EGL") as error:
        Renderer(make_part("box").mesh, 64, 64)
    assert "\n" not in str(error.value) and "libegl1" in str(error.value)
    code = main(["make-scene", "--shape", "box", "--out", str(tmp_path / "scene"), "--detector", "canny"])
    stderr = capsys.readouterr().err
    assert code == 2 and stderr.startswith("edgedog: error: ") and stderr.count("\n") == 1
    assert not (tmp_path / "scene").exists() and list(tmp_path.iterdir()) == []
