"""What a scene's content is, in two digests: its cameras and the bytes of its image files; the
bytes of the edge maps and masks it ships.

A run records it so that `--resume` can tell the scene it trained on from another one at the
same path; the edge-map cache keys its maps with it, so maps of images that changed since are
never reused.
"""

from __future__ import annotations

import hashlib

import numpy as np

from edgedog.errors import InputError
from edgedog.scenes.scene import Scene

CHUNK = 1 << 20


def scene_fingerprint(scene: Scene) -> str:
    """16 hex digits over every view's name, camera (intrinsics, pose, size at file resolution)
    and image file content, in view order. Independent of the downscale and the background."""
    digest = hashlib.sha256()
    for view in scene.views:
        camera = view.camera
        digest.update(view.name.encode("utf-8") + b"\0")
        digest.update(np.asarray(camera.K, np.float64).tobytes())
        digest.update(np.asarray(camera.w2c, np.float64).tobytes())
        digest.update(np.asarray([camera.width, camera.height], np.int64).tobytes())
        _digest_file(digest, view.image_path, "image")
    return digest.hexdigest()[:16]


def maps_fingerprint(scene: Scene) -> str:
    """16 hex digits over the files a scene ships beside its images: every view's edge maps (by
    detector name) and mask, in view order. A run records it beside `scene_fingerprint`, so that
    `--resume` refuses a scene whose maps or masks changed; the edge-map cache needs no part of it
    (it computes maps from the images)."""
    digest = hashlib.sha256()
    for view in scene.views:
        digest.update(view.name.encode("utf-8") + b"\0")
        for name, path in sorted(view.edge_paths.items()):
            digest.update(name.encode("utf-8") + b"\0")
            _digest_file(digest, path, "edge map")
        if view.mask_path is not None:
            digest.update(b"mask\0")
            _digest_file(digest, view.mask_path, "mask")
    return digest.hexdigest()[:16]


def _digest_file(digest, path, what: str) -> None:
    """Feed the content of the file `path` (a view's `what`) to `digest`."""
    try:
        with open(path, "rb") as file:
            while chunk := file.read(CHUNK):
                digest.update(chunk)
    except OSError as exc:
        raise InputError(path, f"cannot read the {what} ({exc.strerror or exc})") from None
