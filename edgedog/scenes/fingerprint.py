"""What a scene's content is, in one digest: its cameras and the bytes of its image files.

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
        try:
            with open(view.image_path, "rb") as file:
                while chunk := file.read(CHUNK):
                    digest.update(chunk)
        except OSError as exc:
            raise InputError(view.image_path, f"cannot read the image ({exc.strerror or exc})") from None
    return digest.hexdigest()[:16]
