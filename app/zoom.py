"""An inspector enlarged to the whole panel: which one, how far it is zoomed and where it looks,
and the pixel under the mouse.

Image pixel coordinates have their centres at integers (pixel (0, 0) covers [-0.5, 0.5]^2,
docs/CONVENTIONS.md). At zoom 1 the image fits the panel; `centre` is the image point at the
middle of the panel, so a screen point s shows image point centre + (s - middle) / scale.
"""

from __future__ import annotations

from dataclasses import dataclass

MAX_ZOOM = 64.0
"""Times the fitted size."""
ZOOM_PER_NOTCH = 1.25


@dataclass(frozen=True)
class Placement:
    """Where an image lies on screen: `middle` (x, y) of the area shows image point `centre`, and
    one image pixel spans `scale` points."""

    middle: tuple[float, float]
    centre: tuple[float, float]
    scale: float

    def to_image(self, x: float, y: float) -> tuple[float, float]:
        """The image point (pixel coordinates) at screen point (x, y)."""
        return (self.centre[0] + (x - self.middle[0]) / self.scale,
                self.centre[1] + (y - self.middle[1]) / self.scale)

    def to_screen(self, u: float, v: float) -> tuple[float, float]:
        """The screen point of image point (u, v)."""
        return (self.middle[0] + (u - self.centre[0]) * self.scale,
                self.middle[1] + (v - self.centre[1]) * self.scale)

    def corners(self, width: int, height: int) -> tuple[tuple[float, float], tuple[float, float]]:
        """The screen rectangle of a width x height image: its outer pixel edges."""
        return self.to_screen(-0.5, -0.5), self.to_screen(width - 0.5, height - 0.5)


def pixel_at(placement: Placement, x: float, y: float, width: int, height: int) -> tuple[int, int] | None:
    """The image pixel under screen point (x, y), None outside the image."""
    u, v = placement.to_image(x, y)
    column, row = int(round(u)), int(round(v))
    return (column, row) if 0 <= column < width and 0 <= row < height else None


@dataclass
class ImageZoom:
    """The inspectors panel's enlarged inspector.

    Attributes:
        enlarged: the inspector filling the panel (a name of inspection.NAMES), None: all side by side.
        zoom: times the size that fits the panel, 1 .. MAX_ZOOM.
        centre: the image point (pixel coordinates) at the middle of the panel; None: the image's.
        hover: the last readout of the pixel under the mouse ('' when the mouse is on no image).
    """

    enlarged: str | None = None
    zoom: float = 1.0
    centre: tuple[float, float] | None = None
    hover: str = ""

    def enlarge(self, name: str | None) -> None:
        """Show inspector `name` alone, fitted (None: all of them again)."""
        self.enlarged, self.zoom, self.centre = name, 1.0, None

    def placement(self, image: tuple[int, int], area: tuple[float, float, float, float]) -> Placement:
        """Where the enlarged image (width, height) lies in `area` (x0, y0, x1, y1), in points."""
        width, height = image
        x0, y0, x1, y1 = area
        fit = min((x1 - x0) / width, (y1 - y0) / height)
        centre = self.centre if self.centre is not None else ((width - 1) / 2, (height - 1) / 2)
        return Placement(((x0 + x1) / 2, (y0 + y1) / 2), centre, fit * self.zoom)

    def zoom_at(self, notches: float, x: float, y: float, image: tuple[int, int],
                area: tuple[float, float, float, float]) -> None:
        """Zoom by mouse-wheel `notches` (positive: closer), keeping the image point under screen
        point (x, y) in place."""
        before = self.placement(image, area)
        point = before.to_image(x, y)
        self.zoom = min(max(self.zoom * ZOOM_PER_NOTCH ** notches, 1.0), MAX_ZOOM)
        scale = self.placement(image, area).scale
        self._look_at((point[0] - (x - before.middle[0]) / scale, point[1] - (y - before.middle[1]) / scale),
                      image)

    def pan(self, dx: float, dy: float, image: tuple[int, int], area: tuple[float, float, float, float]
            ) -> None:
        """Follow a drag of (dx, dy) points: the image moves with the mouse."""
        placed = self.placement(image, area)
        self._look_at((placed.centre[0] - dx / placed.scale, placed.centre[1] - dy / placed.scale), image)

    def _look_at(self, centre: tuple[float, float], image: tuple[int, int]) -> None:
        """Put `centre` at the middle of the panel, kept on the image (fitted: the image's centre)."""
        width, height = image
        if self.zoom <= 1.0:
            self.centre = None
            return
        self.centre = (min(max(centre[0], -0.5), width - 0.5), min(max(centre[1], -0.5), height - 0.5))
