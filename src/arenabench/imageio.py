"""Loading images for the pipeline: always BGR uint8 with three channels, or a clear error;
and :func:`encode_png`, the one PNG encoder every writer uses.

Conversions: grayscale -> BGR; BGRA/RGBA -> BGR by dropping the alpha channel (the colour
channels are what a camera sees; a transparent background keeps whatever colour it stores);
16-bit -> 8-bit by scaling (value / 257, rounded); EXIF orientation is applied as
``cv2.imread`` does. Refused with :class:`ImageLoadError` (a ``ValueError`` whose message is
one line naming the file): a missing path, a directory, an empty file, a truncated PNG or
JPEG (``cv2.imread`` may silently return a partly grey image for those), and anything OpenCV
cannot decode.
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

#: zlib level of :func:`encode_png` (1 = fast; PNG is lossless whatever the level).
PNG_COMPRESSION = 1

_PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
_JPEG_MAGIC = b"\xff\xd8\xff"


class ImageLoadError(ValueError):
    """An image could not be loaded; the message is one line and names the file."""


def _check_complete(data: bytes, name: str) -> None:
    """Raise when a PNG lacks its IEND chunk or a JPEG its end-of-image marker."""
    if data.startswith(_PNG_MAGIC):
        if b"IEND" not in data[-64:]:
            raise ImageLoadError(f"{name}: truncated PNG (no IEND chunk at the end)")
    elif data.startswith(_JPEG_MAGIC):
        tail = data[-256:].rstrip(b"\x00\r\n\t ")
        if not tail.endswith(b"\xff\xd9"):
            raise ImageLoadError(f"{name}: truncated JPEG (no end-of-image marker)")


#: Leading bytes of the formats :func:`image_file_problem` knows without asking OpenCV.
_MAGICS = (_PNG_MAGIC, _JPEG_MAGIC, b"BM", b"II*\x00", b"MM\x00*", b"RIFF", b"P1", b"P2", b"P3",
           b"P4", b"P5", b"P6", b"\x00\x00\x00\x0cjP  ", b"\xff\x4f\xff\x51")


def image_file_problem(path: str | os.PathLike[str]) -> str | None:
    """Why the image file at ``path`` cannot be a whole image, from its first and last bytes
    only (cheap: no decoding), or ``None``.

    Finds an empty file, a file that is no known image format (text, say), and a PNG or JPEG
    cut short (the rules of :func:`decode_image`).
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        with open(p, "rb") as fh:
            head = fh.read(16)
            fh.seek(max(0, size - 256))
            tail = fh.read(256)
    except OSError as exc:
        return f"cannot read ({exc.strerror or exc})"
    if size == 0:
        return "empty file"
    if not head.startswith(_MAGICS) and not cv2.haveImageReader(str(p)):
        return "not an image file (no known image format)"
    try:
        _check_complete(head + tail if size > 16 else head, "image")
    except ImageLoadError as exc:
        return str(exc).removeprefix("image: ")
    return None


def to_bgr8(image: np.ndarray, *, name: str = "image") -> np.ndarray:
    """Convert a decoded image to BGR uint8 with three channels.

    Parameters
    ----------
    image : numpy.ndarray
        uint8 or uint16, H x W or H x W x 1/3/4 (BGR or BGRA order).
    name : str
        Used in error messages.

    Raises
    ------
    ImageLoadError
        For other dtypes or shapes.
    """
    if image.dtype == np.uint16:
        image = cv2.convertScaleAbs(image, alpha=1.0 / 257.0)
    elif image.dtype != np.uint8:
        raise ImageLoadError(f"{name}: unsupported pixel type {image.dtype} (need 8 or 16 bit)")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.ndim == 3 and image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    if image.ndim == 3 and image.shape[2] == 3:
        return np.ascontiguousarray(image)
    raise ImageLoadError(f"{name}: unsupported image shape {image.shape}")


def decode_image(data: bytes, *, name: str = "image") -> np.ndarray:
    """Decode encoded image bytes to BGR uint8 (see the module docstring).

    Raises
    ------
    ImageLoadError
        Empty, truncated or undecodable data; the message starts with ``name``.
    """
    if not data:
        raise ImageLoadError(f"{name}: empty file")
    _check_complete(data, name)
    buf = np.frombuffer(data, dtype=np.uint8)
    try:
        image = cv2.imdecode(buf, cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR)
    except cv2.error as exc:  # some codecs raise instead of returning None
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else "decoder error"
        raise ImageLoadError(f"{name}: not a decodable image ({msg})") from None
    if image is None or image.size == 0:
        raise ImageLoadError(f"{name}: not a decodable image")
    return to_bgr8(image, name=name)


def load_image(path: str | os.PathLike[str]) -> np.ndarray:
    """Read an image file as BGR uint8 (H x W x 3).

    Parameters
    ----------
    path : path-like
        Image file (PNG, JPEG, BMP, TIFF, WebP, ... whatever OpenCV decodes).

    Returns
    -------
    numpy.ndarray
        BGR uint8 image.

    Raises
    ------
    ImageLoadError
        Missing file, directory, not a regular file (FIFO, device), unreadable, empty,
        truncated or not an image.
    """
    p = Path(path)
    name = str(p)
    if not p.exists():
        raise ImageLoadError(f"{name}: no such file")
    if p.is_dir():
        raise ImageLoadError(f"{name}: is a directory, not an image file")
    if not p.is_file():  # a FIFO or a device would block or never end
        raise ImageLoadError(f"{name}: not a regular file (a pipe, device or socket)")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ImageLoadError(f"{name}: cannot read ({exc.strerror or exc})") from None
    return decode_image(data, name=name)


def encode_png(bgr: np.ndarray) -> bytes:
    """Encode an image as PNG bytes, as every arenabench writer does (dataset images, the
    single ``render``, a sweep's kept images): zlib level :data:`PNG_COMPRESSION` and, with
    OpenCV >= 4.11, no row filter (2-3x faster).

    Parameters
    ----------
    bgr : numpy.ndarray
        uint8 image, H x W x 3 in OpenCV's BGR order (or H x W grey).

    Returns
    -------
    bytes
        The PNG file's content (the same bytes for the same pixels and OpenCV).
    """
    params = [cv2.IMWRITE_PNG_COMPRESSION, PNG_COMPRESSION]
    if hasattr(cv2, "IMWRITE_PNG_FILTER"):
        params += [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE]
    ok, buf = cv2.imencode(".png", bgr, params)
    if not ok:  # pragma: no cover - OpenCV failure
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()
