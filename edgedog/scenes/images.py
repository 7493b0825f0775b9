"""Reading images, edge maps and masks from disk, with size checks and downscaling.

`image_info` reads what a scene needs to know of a file (size, alpha, whether it is whole) from
its header, so that a scene can check every file when it loads without decoding them all.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import cv2
import numpy as np

from edgedog.errors import InputError

Background = tuple[float, float, float] | None
"""RGB in [0, 1] to composite RGBA images on, or None to drop the alpha channel."""

MAX_IMAGE_PIXELS = 1 << 27
"""Most pixels one image may have (134 megapixels, e.g. 16384 x 8192): more than the photos of a
100-megapixel camera (11648 x 8736), while its float32 RGBA copy alone already takes 2 GiB."""

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
JPEG_SIGNATURE = b"\xff\xd8"
# JPEG markers of a frame header (SOF0 to SOF15 but DHT, JPG and DAC), which hold the size.
JPEG_FRAME_MARKERS = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# JPEG markers that stand alone (no length): TEM, RST0 to RST7, SOI.
JPEG_BARE_MARKERS = frozenset([0x01, *range(0xD0, 0xD9)])
SCAN_CHUNK = 1 << 20


@dataclass(frozen=True)
class ImageInfo:
    """What a scene needs to know of an image file before decoding it.

    Attributes:
        width, height: size in pixels.
        alpha: whether `read_raw` returns an alpha channel (4 channels) for it.
    """

    width: int
    height: int
    alpha: bool


class _Damaged(Exception):
    """The file's structure says it is cut short or not what its signature claims."""


def image_info(path: Path) -> ImageInfo:
    """Size and alpha of an image file, from its header for PNG and JPEG (the file is not
    decoded), else by decoding it.

    Raises:
        InputError naming the file when it is missing, cut short (a PNG without its IEND chunk,
        a JPEG without the end of its image data: OpenCV decodes such JPEGs silently, greying
        what is missing), damaged, or larger than MAX_IMAGE_PIXELS.
    """
    info = _header(path)
    return _bounded(path, info if info is not None else _info_of(_decode(path)))


def _header(path: Path) -> ImageInfo | None:
    """ImageInfo of a PNG or JPEG file from its structure (checked whole); None for other formats."""
    if not path.is_file():
        raise InputError(path, "file not found")
    with open(path, "rb") as file:
        signature = file.read(8)
        for kind, magic, reader in (("PNG", PNG_SIGNATURE, _png_info), ("JPEG", JPEG_SIGNATURE, _jpeg_info)):
            if signature.startswith(magic):
                try:
                    return reader(file)
                except (_Damaged, struct.error) as exc:
                    raise InputError(path, f"cannot be decoded as an image (a damaged or truncated "
                                           f"{kind}: {exc})") from None
    return None


def _bounded(path: Path, info: ImageInfo) -> ImageInfo:
    if info.width < 1 or info.height < 1:
        raise InputError(path, f"image header declares {info.width}x{info.height} pixels")
    if info.width * info.height > MAX_IMAGE_PIXELS:
        raise InputError(path, f"image is {info.width}x{info.height} pixels, more than the "
                               f"{MAX_IMAGE_PIXELS / 1e6:.0f} megapixels an image may have")
    return info


def _info_of(image: np.ndarray) -> ImageInfo:
    return ImageInfo(image.shape[1], image.shape[0], image.ndim == 3 and image.shape[2] == 4)


def _decode(path: Path) -> np.ndarray:
    """The file as OpenCV decodes it, colour as RGB(A) (OpenCV refuses more than 2^30 pixels)."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise InputError(path, "cannot be decoded as an image")
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2RGBA if image.shape[2] == 4 else cv2.COLOR_BGR2RGB
        image = cv2.cvtColor(image, code)
    return image


def _exactly(file: BinaryIO, count: int) -> bytes:
    data = file.read(count)
    if len(data) != count:
        raise _Damaged("it stops early")
    return data


def _png_info(file: BinaryIO) -> ImageInfo:
    """Walk the chunks after the signature up to IEND (seeking over their data).

    Alpha as OpenCV decodes it: grey+alpha and RGBA always; RGB and palette images when they
    carry a tRNS chunk; grey images never (OpenCV drops their tRNS).
    """
    length, kind = struct.unpack(">I4s", _exactly(file, 8))
    if kind != b"IHDR" or length != 13:
        raise _Damaged("no IHDR chunk first")
    width, height, _, colour = struct.unpack(">IIBB", _exactly(file, 10))
    file.seek(length - 10 + 4, 1)  # the rest of IHDR and its CRC
    transparency = False
    kind = b""
    while kind != b"IEND":
        length, kind = struct.unpack(">I4s", _exactly(file, 8))
        transparency |= kind == b"tRNS"
        file.seek(length, 1)
        _exactly(file, 4)  # the CRC: reading it past the end means the chunk was cut short
    alpha = colour in (4, 6) or (colour in (2, 3) and transparency)
    return ImageInfo(width, height, alpha)


def _jpeg_info(file: BinaryIO) -> ImageInfo:
    """Walk the segments after SOI to the first scan (its frame header gives the size), then
    look for the EOI marker after it: the entropy-coded data escapes every 0xFF, so the first
    FF D9 after the first scan ends the image (data appended after it, as in motion photos,
    is allowed)."""
    file.seek(2)
    size = None
    while True:
        marker = _exactly(file, 2)
        if marker[0] != 0xFF:
            raise _Damaged(f"no segment marker at byte {file.tell() - 2}")
        code = marker[1]
        while code == 0xFF:  # fill bytes before a marker
            code = _exactly(file, 1)[0]
        if code in JPEG_BARE_MARKERS:
            continue
        if code == 0xD9:
            raise _Damaged("the image ends before any image data")
        (length,) = struct.unpack(">H", _exactly(file, 2))
        if length < 2:
            raise _Damaged(f"a segment of length {length}")
        if code == 0xDA:
            break
        if code in JPEG_FRAME_MARKERS:
            _, height, width = struct.unpack(">BHH", _exactly(file, length - 2)[:5])
            size = (width, height)
        else:
            file.seek(length - 2, 1)
    if size is None:
        raise _Damaged("no frame header before the image data")
    tail = b""
    while chunk := file.read(SCAN_CHUNK):
        if b"\xff\xd9" in tail[-1:] + chunk:
            return ImageInfo(size[0], size[1], False)
        tail = chunk
    raise _Damaged("the image data stops before its end (EOI) marker")


def read_raw(path: Path, expected_size: tuple[int, int] | None = None,
             also_allowed: tuple[int, int] | None = None) -> np.ndarray:
    """Decode an image file as stored (8 or 16 bit, 1, 3 or 4 channels; colour as RGB(A)).

    Args:
        path: the file.
        expected_size: (width, height) the scene's camera declares for it, checked when given.
        also_allowed: another accepted (width, height), e.g. the downscaled size of a cached map.
    Returns:
        (H, W) or (H, W, C) array of the file's dtype.
    """
    header = _header(path)
    if header is not None:  # a cut short or too large file fails before decoding
        _bounded(path, header)
    image = _decode(path)
    info = _bounded(path, _info_of(image))
    if expected_size is not None and (info.width, info.height) not in (tuple(expected_size), also_allowed):
        raise InputError(path, f"image is {info.width}x{info.height} pixels but the camera expects "
                               f"{expected_size[0]}x{expected_size[1]}")
    return image


def to_unit_float(image: np.ndarray) -> np.ndarray:
    """Integer image -> float32 in [0, 1] (by the dtype's maximum)."""
    if np.issubdtype(image.dtype, np.integer):
        return image.astype(np.float32) / np.iinfo(image.dtype).max
    return image.astype(np.float32)


def to_u8(image: np.ndarray) -> np.ndarray:
    """Float image in [0, 1] -> uint8, rounded to nearest (values outside are clipped)."""
    return np.clip(image * 255.0 + 0.5, 0, 255).astype(np.uint8)


def resize_to(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """Area-averaging resize (no-op at the same size); keeps the channel layout."""
    if image.shape[1] == width and image.shape[0] == height:
        return image
    return cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)


def as_rgb(image: np.ndarray, background: Background) -> np.ndarray:
    """(H, W[, C]) float image -> (H, W, 3) RGB, compositing alpha on `background`."""
    if image.ndim == 2:
        return np.repeat(image[..., None], 3, axis=2)
    if image.shape[2] == 4:
        rgb, alpha = image[..., :3], image[..., 3:]
        if background is None:
            return np.ascontiguousarray(rgb)
        return rgb * alpha + np.asarray(background, np.float32) * (1.0 - alpha)
    return image[..., :3]


def as_gray(image: np.ndarray) -> np.ndarray:
    """(H, W[, C]) float image -> (H, W) single channel (mean of RGB; alpha ignored)."""
    if image.ndim == 2:
        return image
    return image[..., :3].mean(axis=2) if image.shape[2] >= 3 else image[..., 0]


def parse_background(text: str) -> Background:
    """'black' | 'white' | 'none' | 'R,G,B' (floats in [0, 1]) -> Background."""
    named = {"black": (0.0, 0.0, 0.0), "white": (1.0, 1.0, 1.0), "none": None}
    if text in named:
        return named[text]
    parts = text.split(",")
    try:
        rgb = tuple(float(p) for p in parts)
    except ValueError:
        rgb = ()
    if len(rgb) != 3 or not all(0.0 <= c <= 1.0 for c in rgb):
        raise ValueError(f"background must be black, white, none or R,G,B in [0, 1], got {text!r}")
    return rgb
