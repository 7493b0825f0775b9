"""The renderer's ABC-NEF lighting reproduces ABC-NEF's own renders: 00000006's mesh drawn with its
cameras matches its images to a few grey levels where both show a face (the inside of its hole,
near-white in ABC-NEF's images, left out as when the lighting was fitted)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from edgedog.scenes import load_scene
from tests.helpers.paths import shared_path

VIEWS = (0, 17, 33)


@pytest.fixture(scope="module")
def renders_and_images():
    """For VIEWS of 00000006: (our abc-nef render, our two-lights render, ABC-NEF's image), each
    (H, W, 4) uint8 RGBA."""
    from edgedog.synthetic.abc_file import abc_part
    from edgedog.synthetic.render import GLUnavailableError, Renderer

    folder = shared_path("abc_nef/00000006")
    part = abc_part(next((folder / "gt").glob("*.obj")), next((folder / "gt").glob("*features*.yml")))
    scene = load_scene(folder)
    views = [scene.views[index] for index in VIEWS]
    renders = {}
    try:
        for lighting in ("abc-nef", "two-lights"):  # one GL context at a time
            with Renderer(part.mesh, 800, 800, lighting) as renderer:
                renders[lighting] = [renderer.render(view.camera).rgba for view in views]
    except GLUnavailableError as exc:
        pytest.skip(str(exc))
    images = [cv2.cvtColor(cv2.imread(str(view.image_path), cv2.IMREAD_UNCHANGED), cv2.COLOR_BGRA2RGBA)
              for view in views]
    return list(zip(renders["abc-nef"], renders["two-lights"], images))


def interior_greys(ours: np.ndarray, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Grey levels (0-255) of both at the pixels where both are opaque, 2 px away from any outline,
    and ABC-NEF's image is not near-white (the hole's inside)."""
    both = ((ours[..., 3] == 255) & (image[..., 3] == 255)).astype(np.uint8)
    inside = cv2.erode(both, np.ones((5, 5), np.uint8)) > 0
    theirs = image[..., :3].mean(axis=2)
    inside &= theirs < 0.92 * 255
    return ours[..., :3].mean(axis=2)[inside], theirs[inside]


def test_the_abc_nef_lighting_matches_abc_nefs_renders(renders_and_images):
    for abc_nef, two_lights, image in renders_and_images:
        ours, theirs = interior_greys(abc_nef, image)
        assert len(ours) > 20_000
        error = ours - theirs
        assert np.sqrt(np.mean(error ** 2)) < 8.0 and abs(error.mean()) < 3.0
        # the built-in look is far from ABC-NEF's: the comparison can fail
        ours, theirs = interior_greys(two_lights, image)
        assert np.sqrt(np.mean((ours - theirs) ** 2)) > 40.0


def test_an_unknown_lighting_is_refused():
    from edgedog.synthetic.render import Renderer
    from edgedog.synthetic.shapes import make_part

    with pytest.raises(ValueError, match="lighting 'studio'"):
        Renderer(make_part("box").mesh, 16, 16, "studio")
