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
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import cv2
import numpy as np

from arenabench.fileio import open_regular, read_regular
from arenabench.limits import MAX_IMAGE_SIDE_PX

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

    Finds an empty file, a file that is no known image format (text, say), a PNG or JPEG
    cut short (the rules of :func:`decode_image`), and a PNG or JPEG whose header declares a
    side of 0 or beyond :data:`~arenabench.limits.MAX_IMAGE_SIDE_PX` (:func:`declared_size`).
    """
    p = Path(path)
    try:
        with open_regular(p) as fh:  # never blocks on a FIFO
            size = os.fstat(fh.fileno()).st_size
            head = fh.read(16)
            fh.seek(max(0, size - 256))
            tail = fh.read(256)
            sides = _header_size(fh)
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
    if sides is not None and (min(sides) < 1 or max(sides) > MAX_IMAGE_SIDE_PX):
        return (f"its header declares {sides[0]} x {sides[1]} px (a side is 1 to "
                f"{MAX_IMAGE_SIDE_PX} px)")
    return None


#: JPEG start-of-frame markers (baseline, progressive, lossless...): they hold the size.
_JPEG_SOF = frozenset({0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD,
                       0xCE, 0xCF})
#: Most JPEG segments looked at before the frame header (EXIF, ICC... come first).
_JPEG_MAX_SEGMENTS = 64


def declared_size(path: str | os.PathLike[str]) -> tuple[int, int] | None:
    """Width and height a PNG's ``IHDR`` or a JPEG's frame header declares, read from the
    header alone (no decoding); ``None`` for other formats or a header not found.

    A header may promise more pixels than the file holds (a 20000 x 20000 PNG of a few
    bytes): :func:`image_file_problem` refuses a side beyond
    :data:`~arenabench.limits.MAX_IMAGE_SIDE_PX` before any decoder allocates for it.
    """
    with open(path, "rb") as fh:
        return _header_size(fh)


def _header_size(fh: Any) -> tuple[int, int] | None:
    """:func:`declared_size` of the open binary file ``fh`` (read from its start)."""
    import struct

    fh.seek(0)
    head = fh.read(24)
    if head.startswith(_PNG_MAGIC):
        if len(head) < 24 or head[12:16] != b"IHDR":
            return None
        width, height = struct.unpack(">II", head[16:24])
        return int(width), int(height)
    if not head.startswith(_JPEG_MAGIC):
        return None
    fh.seek(2)
    for _ in range(_JPEG_MAX_SEGMENTS):
        marker = fh.read(4)
        if len(marker) < 4 or marker[0] != 0xFF:
            return None
        length = struct.unpack(">H", marker[2:4])[0]
        if marker[1] in _JPEG_SOF:
            frame = fh.read(5)
            if len(frame) < 5:
                return None
            height, width = struct.unpack(">HH", frame[1:5])
            return int(width), int(height)
        if length < 2:
            return None
        fh.seek(length - 2, os.SEEK_CUR)
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
    return decode_image(read_image_bytes(p), name=name)


def read_image_bytes(path: str | os.PathLike[str]) -> bytes:
    """The bytes of an image file, read only if it is a regular file (never blocking on a
    FIFO that takes the place of an image: :func:`arenabench.fileio.open_regular`).

    Raises
    ------
    ImageLoadError
        When it is not a regular file or cannot be read (one line naming the file).
    """
    try:
        return read_regular(path)
    except OSError as exc:
        raise ImageLoadError(f"{path}: cannot read ({exc.strerror or exc})") from None


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


#: Image file formats a dataset can be written in (``output.format``) and their file extension.
IMAGE_EXTENSIONS = {"png": "png", "jpeg": "jpg"}


#: JPEG chroma subsamplings the writers can choose (``output.jpeg_subsampling``): name ->
#: (the (horizontal, vertical) sampling factors of Y, Cb and Cr in the frame header, the
#: OpenCV ``IMWRITE_JPEG_SAMPLING_FACTOR_*`` constant's name). ``420`` is what
#: ``cv2.imwrite`` writes by default, and the competition's example.
JPEG_SUBSAMPLINGS: dict[str, tuple[tuple[tuple[int, int], ...], str]] = {
    "420": (((2, 2), (1, 1), (1, 1)), "IMWRITE_JPEG_SAMPLING_FACTOR_420"),
    "422": (((2, 1), (1, 1), (1, 1)), "IMWRITE_JPEG_SAMPLING_FACTOR_422"),
    "444": (((1, 1), (1, 1), (1, 1)), "IMWRITE_JPEG_SAMPLING_FACTOR_444"),
}
#: The subsampling ``cv2.imwrite`` uses when not told (written without the option).
DEFAULT_JPEG_SUBSAMPLING = "420"


def jpeg_subsampling_problem(subsampling: str) -> str | None:
    """Why :func:`encode_jpeg` cannot write ``subsampling`` with this OpenCV, or ``None``.

    Any OpenCV writes the default (``420``); the others need ``IMWRITE_JPEG_SAMPLING_FACTOR``
    (OpenCV 4.7 and later; the competition's 4.10 has it).
    """
    if subsampling not in JPEG_SUBSAMPLINGS:
        return (f"unknown JPEG subsampling {subsampling!r} "
                f"(one of {', '.join(JPEG_SUBSAMPLINGS)})")
    if subsampling != DEFAULT_JPEG_SUBSAMPLING and not hasattr(
            cv2, "IMWRITE_JPEG_SAMPLING_FACTOR"):
        return (f"JPEG subsampling {subsampling} needs OpenCV >= 4.7 "
                f"(IMWRITE_JPEG_SAMPLING_FACTOR); this OpenCV {cv2.__version__} writes "
                f"{DEFAULT_JPEG_SUBSAMPLING} only")
    return None


def encode_jpeg(bgr: np.ndarray, *, quality: int,
                subsampling: str = DEFAULT_JPEG_SUBSAMPLING) -> bytes:
    """Encode an image as JPEG bytes as ``cv2.imwrite`` does (libjpeg's standard tables scaled
    to ``quality``, baseline), with 4:2:0 chroma subsampling by default: how the competition's
    example image was written.

    Parameters
    ----------
    bgr : numpy.ndarray
        uint8 image, H x W x 3 in OpenCV's BGR order (or H x W grey).
    quality : int, keyword-only
        JPEG quality, 1..100.
    subsampling : {"420", "422", "444"}, keyword-only
        Chroma subsampling (:data:`JPEG_SUBSAMPLINGS`); ``420`` is written without the
        option, as ``cv2.imwrite``'s default.

    Raises
    ------
    ValueError
        For a quality outside 1..100, or a subsampling this OpenCV cannot write
        (:func:`jpeg_subsampling_problem`).
    """
    if isinstance(quality, bool) or not isinstance(quality, int) or not 1 <= quality <= 100:
        raise ValueError(f"JPEG quality must be an integer 1..100, got {quality!r}")
    if problem := jpeg_subsampling_problem(subsampling):
        raise ValueError(problem)
    params = [cv2.IMWRITE_JPEG_QUALITY, quality]
    if subsampling != DEFAULT_JPEG_SUBSAMPLING:
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR,
                   getattr(cv2, JPEG_SUBSAMPLINGS[subsampling][1])]
    ok, buf = cv2.imencode(".jpg", bgr, params)
    if not ok:  # pragma: no cover - OpenCV failure
        raise RuntimeError("JPEG encoding failed")
    return buf.tobytes()


def encode_image(bgr: np.ndarray, *, image_format: str, jpeg_quality: int,
                 jpeg_subsampling: str = DEFAULT_JPEG_SUBSAMPLING) -> bytes:
    """Encode ``bgr`` in ``image_format`` (a key of :data:`IMAGE_EXTENSIONS`):
    :func:`encode_png` or :func:`encode_jpeg` at ``jpeg_quality`` and ``jpeg_subsampling``.

    Raises
    ------
    ValueError
        For an unknown format.
    """
    if image_format == "png":
        return encode_png(bgr)
    if image_format == "jpeg":
        return encode_jpeg(bgr, quality=jpeg_quality, subsampling=jpeg_subsampling)
    raise ValueError(f"unknown image format {image_format!r} "
                     f"(one of {', '.join(IMAGE_EXTENSIONS)})")


@dataclass(frozen=True)
class JpegLayout:
    """What a baseline/progressive JPEG file says about how it was encoded.

    Attributes
    ----------
    tables : dict
        Quantisation table id -> its 64 values in file (zig-zag) order (DQT segments).
    sampling : tuple of (int, int)
        (horizontal, vertical) sampling factors of each frame component (SOF segment), e.g.
        ``((2, 2), (1, 1), (1, 1))`` for 4:2:0 colour.
    """

    tables: dict[int, tuple[int, ...]]
    sampling: tuple[tuple[int, int], ...]


def jpeg_layout(data: bytes, *, name: str = "image") -> JpegLayout:
    """Read the quantisation tables (DQT) and sampling factors (SOF0..SOF2) of a JPEG file.

    Raises
    ------
    ImageLoadError
        When ``data`` is not a JPEG or its segments up to the scan are malformed.
    """
    if not data.startswith(_JPEG_MAGIC):
        raise ImageLoadError(f"{name}: not a JPEG file")
    tables: dict[int, tuple[int, ...]] = {}
    sampling: tuple[tuple[int, int], ...] = ()
    pos = 2
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            raise ImageLoadError(f"{name}: malformed JPEG segment at byte {pos}")
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        length = int.from_bytes(data[pos + 2:pos + 4], "big")
        body = data[pos + 4:pos + 2 + length]
        if length < 2 or len(body) != length - 2:
            raise ImageLoadError(f"{name}: truncated JPEG segment at byte {pos}")
        if marker == 0xDB:  # DQT: one or more tables
            k = 0
            while k < len(body):
                precision, table_id = body[k] >> 4, body[k] & 0x0F
                size = 128 if precision else 64
                raw = body[k + 1:k + 1 + size]
                values = (tuple(int.from_bytes(raw[i:i + 2], "big") for i in range(0, 128, 2))
                          if precision else tuple(raw))
                if len(values) != 64:
                    raise ImageLoadError(f"{name}: truncated JPEG quantisation table")
                tables[table_id] = values
                k += 1 + size
        elif marker in (0xC0, 0xC1, 0xC2):  # SOF: components and their sampling
            n = body[5]
            sampling = tuple((body[6 + 3 * c + 1] >> 4, body[6 + 3 * c + 1] & 0x0F)
                             for c in range(n))
        elif marker == 0xDA:  # start of scan: the tables come before it
            break
        pos += 2 + length
    if not tables or not sampling:
        raise ImageLoadError(f"{name}: JPEG without quantisation tables or frame header")
    return JpegLayout(tables=tables, sampling=sampling)


#: The example quantisation tables of the JPEG standard (ITU-T T.81, Annex K, tables K.1 and
#: K.2), in natural (row-major) order: libjpeg scales them by the quality.
_STD_LUMINANCE = (
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55,
    14, 13, 16, 24, 40, 57, 69, 56, 14, 17, 22, 29, 51, 87, 80, 62,
    18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113, 92,
    49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99,
)  # fmt: skip
_STD_CHROMINANCE = (
    17, 18, 24, 47, 99, 99, 99, 99, 18, 21, 26, 66, 99, 99, 99, 99,
    24, 26, 56, *(99,) * 5, 47, 66, *(99,) * 6, *(99,) * 32,
)  # fmt: skip
#: Position in natural order of the k-th value of a table as the file stores it (zig-zag).
_ZIGZAG = (
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5,
    12, 19, 26, 33, 40, 48, 41, 34, 27, 20, 13, 6, 7, 14, 21, 28,
    35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51,
    58, 59, 52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63,
)  # fmt: skip


def libjpeg_table(standard: tuple[int, ...], quality: int) -> tuple[int, ...]:
    """A standard table (natural order) scaled to ``quality`` as libjpeg's
    ``jpeg_set_quality`` scales it (``jpeg_quality_scaling``, then ``jpeg_add_quant_table``
    with ``force_baseline``), in file (zig-zag) order."""
    scale = 5000 // quality if quality < 50 else 200 - 2 * quality
    return tuple(min(max((standard[i] * scale + 50) // 100, 1), 255) for i in _ZIGZAG)


_LIBJPEG_TABLES = {q: (libjpeg_table(_STD_LUMINANCE, q), libjpeg_table(_STD_CHROMINANCE, q))
                   for q in range(1, 101)}


class JpegSettings(NamedTuple):
    """How a JPEG file was written, as far as its own headers say (:func:`jpeg_settings`)."""

    #: libjpeg quality 1..100: exact when the file's tables are libjpeg's standard ones
    #: scaled to it (:func:`jpeg_quality`), else the nearest such luminance table's.
    quality: int
    #: chroma subsampling: a key of :data:`JPEG_SUBSAMPLINGS`, ``440`` or ``411``, ``gray``
    #: for one component, else the factors (``"2x2,1x1,1x1"``).
    subsampling: str


_OTHER_SUBSAMPLINGS = {((1, 2), (1, 1), (1, 1)): "440", ((4, 1), (1, 1), (1, 1)): "411"}


def _subsampling_name(sampling: tuple[tuple[int, int], ...]) -> str:
    for name, (factors, _) in JPEG_SUBSAMPLINGS.items():
        if sampling == factors:
            return name
    if len(sampling) == 1:
        return "gray"
    return _OTHER_SUBSAMPLINGS.get(sampling, ",".join(f"{h}x{v}" for h, v in sampling))


def _exact_quality(layout: JpegLayout) -> int | None:
    luma, chroma = layout.tables.get(0), layout.tables.get(1)
    for quality, (lum, chrom) in _LIBJPEG_TABLES.items():
        if luma == lum and (chroma is None or chroma == chrom):
            return quality
    return None


def jpeg_settings(data: bytes, *, name: str = "image") -> JpegSettings:
    """The quality and chroma subsampling a JPEG file was written with, read from its own
    quantisation tables (DQT) and frame header (SOF): no decoding.

    The quality is libjpeg's (``cv2.imwrite``'s, Pillow's, most cameras' software): exact
    when the luminance table (and the chrominance one, when present) is the JPEG standard's
    scaled to that quality, as libjpeg scales it; otherwise the quality whose scaled
    luminance table is nearest (least sum of absolute differences; an estimate, for an
    encoder with tables of its own).

    Raises
    ------
    ImageLoadError
        When ``data`` is not a readable JPEG or has no luminance table (id 0).
    """
    layout = jpeg_layout(data, name=name)
    if 0 not in layout.tables:
        raise ImageLoadError(f"{name}: JPEG without a luminance quantisation table (id 0)")
    quality = _exact_quality(layout)
    if quality is None:
        luma = np.asarray(layout.tables[0], np.int64)
        quality = min(_LIBJPEG_TABLES, key=lambda q: (
            int(np.abs(np.asarray(_LIBJPEG_TABLES[q][0]) - luma).sum()), -q))
    return JpegSettings(quality=quality, subsampling=_subsampling_name(layout.sampling))


def jpeg_quality(data: bytes, *, name: str = "image") -> int | None:
    """The quality at which :func:`encode_jpeg` (``cv2.imwrite``'s encoder) writes the same
    quantisation tables as this JPEG file (libjpeg's standard tables scaled to it), or None
    when no quality does (:func:`jpeg_settings` then estimates one).

    Raises
    ------
    ImageLoadError
        When ``data`` is not a readable JPEG.
    """
    return _exact_quality(jpeg_layout(data, name=name))
