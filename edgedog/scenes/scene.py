"""The one scene type every loader returns: posed views, their files, bounds."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from edgedog.errors import InputError
from edgedog.scenes.camera import Camera
from edgedog.scenes.distortion import Distortion
from edgedog.scenes.images import Background, as_gray, as_rgb, read_raw, resize_to, to_unit_float
from edgedog.scenes.read_cache import DEFAULT_MAX_BYTES, ReadCache


@dataclass(frozen=True)
class View:
    """One posed image and the files that belong to it.

    Attributes:
        name: stable identifier (the image file's stem).
        camera: the camera at the resolution of the files on disk.
        image_path: the colour image (RGB or RGBA).
        edge_paths: detector name (lower case, e.g. "pidinet") -> pseudo-edge map file.
        mask_path: object mask file, if the dataset has one (RGBA images carry their own).
        alpha: whether the image has an alpha channel (its mask), as its header says; None when
            not known before the image is read.
        distortion: the lens distortion of the files on disk, with `camera` their distorted
            camera's intrinsics; None for a pinhole. `load_scene` undistorts such views.
    """

    name: str
    camera: Camera
    image_path: Path
    edge_paths: Mapping[str, Path] = field(default_factory=dict)
    mask_path: Path | None = None
    alpha: bool | None = None
    distortion: Distortion | None = None

    @property
    def has_mask(self) -> bool:
        return self.mask_path is not None or bool(self.alpha)


@dataclass
class Scene:
    """A multi-view dataset. Images load lazily, one view at a time.

    Attributes:
        root: the folder the scene was loaded from.
        format: "nerf" | "nerfstudio" | "emap" | "neus" | "colmap".
        views: the training views, cameras at file resolution.
        bounds: (2, 3) axis-aligned box [min, max] that holds the object, world units.
        world_to_gt: (4, 4) transform from the world frame to the ground-truth frame.
        sfm_points: (N, 3) structure-from-motion points for initialisation, or None.
        sfm_colors: (N, 3) uint8 colours of sfm_points, or None.
        downscale: integer factor applied to images and intrinsics on load.
        background: what RGBA images are composited on (None drops the alpha channel).
        damaged: image file -> why it cannot be read (cut short, undecodable, too large), for
            the images found so when the scene loaded; reading one raises that InputError.
        skipped: image file -> its problem, for the views `without_damaged` took out.
        read_cache: where edge maps and coverage are kept once decoded (`with_read_cache`);
            None: every call reads its file.
    """

    root: Path
    format: str
    views: list[View]
    bounds: np.ndarray
    world_to_gt: np.ndarray = field(default_factory=lambda: np.eye(4))
    sfm_points: np.ndarray | None = None
    sfm_colors: np.ndarray | None = None
    downscale: int = 1
    background: Background = (0.0, 0.0, 0.0)
    damaged: dict[Path, str] = field(default_factory=dict)
    skipped: dict[Path, str] = field(default_factory=dict)
    read_cache: ReadCache | None = field(default=None, compare=False, repr=False)

    def with_read_cache(self, max_bytes: int = DEFAULT_MAX_BYTES) -> Scene:
        """The scene, its edge maps and coverage kept once read (at most `max_bytes`, read-only
        arrays); this scene is left reading its files."""
        return dataclasses.replace(self, read_cache=ReadCache(max_bytes))

    def _cached(self, key: tuple, read):
        """`read()`, through the read cache when the scene has one. `key` names the file and
        what is made of it; the loaded size is added, so that a rescaled scene reads afresh."""
        if self.read_cache is None:
            return read()
        return self.read_cache.get((*key, self.downscale), read)

    def without_damaged(self) -> Scene:
        """The scene without the views whose image is damaged (recorded in `skipped`)."""
        views = [view for view in self.views if view.image_path not in self.damaged]
        return dataclasses.replace(self, views=views, damaged={}, skipped={**self.skipped, **self.damaged})

    def __len__(self) -> int:
        return len(self.views)

    @property
    def detectors(self) -> list[str]:
        """Detector names that have an edge map for every view."""
        if not self.views:
            return []
        names = set(self.views[0].edge_paths)
        for view in self.views[1:]:
            names &= set(view.edge_paths)
        return sorted(names)

    def camera(self, index: int) -> Camera:
        """Camera of view `index` at the loaded (downscaled) resolution."""
        full = self.views[index].camera
        return full.scaled(full.width // self.downscale, full.height // self.downscale)

    @property
    def cameras(self) -> list[Camera]:
        return [self.camera(i) for i in range(len(self.views))]

    def _read(self, path: Path, index: int) -> np.ndarray:
        """File -> float32 at the loaded resolution, checked against the view's camera.

        Files at the camera's resolution are resized; files already at the loaded resolution
        (edge maps computed after downscaling) are used as they are.
        """
        full, loaded = self.views[index].camera, self.camera(index)
        image = to_unit_float(read_raw(path, (full.width, full.height), (loaded.width, loaded.height)))
        return resize_to(image, loaded.width, loaded.height)

    def load_image(self, index: int) -> np.ndarray:
        """(H, W, 3) float32 RGB in [0, 1]."""
        return as_rgb(self._read(self.views[index].image_path, index), self.background)

    def load_edge_map(self, index: int, detector: str | None = None) -> np.ndarray:
        """(H, W) float32 pseudo-edge map in [0, 1] (1 = edge).

        Args:
            detector: which detector's maps; defaults to the first of `detectors`.
        """
        view = self.views[index]
        if detector is None:
            if not self.detectors:
                raise InputError(self.root, "the scene has no edge maps; compute them first")
            detector = self.detectors[0]
        if detector not in view.edge_paths:
            raise InputError(
                self.root,
                f"no '{detector}' edge map for view {view.name} "
                f"(available: {', '.join(sorted(view.edge_paths)) or 'none'})",
            )
        path = view.edge_paths[detector]
        return self._cached(("edge", path), lambda: as_gray(self._read(path, index)))

    @property
    def masked_views(self) -> list[int]:
        """Indices of the views with a mask: a mask file or an image with an alpha channel."""
        return [i for i, view in enumerate(self.views) if view.has_mask]

    def load_coverage(self, index: int) -> np.ndarray | None:
        """(H, W) float32 share of each pixel covered by the object, in [0, 1], from the mask
        file or the image's alpha. Anti-aliased borders keep fractional values.

        Returns None when no view of the scene has a mask. Raises InputError naming the image
        when only this view lacks one: a scene whose images carry alpha in some views only
        (grey or RGB images among RGBA ones) is decided view by view, and this one has none.
        """
        view = self.views[index]
        source = view.mask_path or view.image_path
        return self._cached(("coverage", source), lambda: self._read_coverage(index))

    def _read_coverage(self, index: int) -> np.ndarray | None:
        """`load_coverage` from the files."""
        view = self.views[index]
        if view.mask_path is not None:
            return as_gray(self._read(view.mask_path, index))
        masked = len(self.masked_views)
        if view.alpha is False and not masked:
            return None
        image = self._read(view.image_path, index)  # a damaged image fails here, naming itself
        if image.ndim == 3 and image.shape[2] == 4:
            return np.ascontiguousarray(image[..., 3])
        if masked:
            raise InputError(view.image_path, f"has no alpha channel (no mask), while {masked} of the "
                                              f"scene's {len(self)} views' images have one")
        return None

    def load_mask(self, index: int) -> np.ndarray | None:
        """(H, W) bool object mask (coverage > 0.5); None if the scene has no masks (see
        `load_coverage`)."""
        coverage = self.load_coverage(index)
        return None if coverage is None else coverage > 0.5
