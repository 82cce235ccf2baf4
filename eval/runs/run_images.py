"""Images an external run left in its working directory (its warp, an annotated copy...), kept
as small thumbnails so that a failure card can show what the script itself saw.

Many team scripts save their warped arena in their working directory (``transformed_image.png``,
``output_image.jpg``...). :func:`collect_run_images` reads them after the run, from the one place
every cold and warm run goes through (:func:`arenabench.eval.runs.predictions.prediction_from_run`),
before the run's folder is removed. The run is hostile, so every step is bounded (the limits
are declared in :mod:`arenabench.limits`):

- at most :data:`~arenabench.limits.MAX_RUN_IMAGE_ENTRIES` entries of the folder's top level
  are looked at; only regular files named ``*.png``, ``*.jpg`` or ``*.jpeg`` (any case), never
  a link (opened with ``O_NOFOLLOW``), a FIFO or a folder, and not the harness's copy of the
  input image (``image.png``, ``image.jpg``...: :data:`INPUT_COPY_NAMES`);
- a file larger than :data:`~arenabench.limits.MAX_RUN_IMAGE_BYTES` is skipped, as is one
  whose header (:func:`image_size`, nothing decoded) is not PNG or JPEG or states more than
  :data:`~arenabench.limits.MAX_RUN_IMAGE_PIXELS` px; what OpenCV cannot decode is skipped;
- the first :data:`~arenabench.limits.MAX_RUN_IMAGES` (by name) are kept, each scaled down to
  :data:`~arenabench.limits.RUN_IMAGE_THUMB_PX` px on its longer side and encoded as JPEG.

Nothing here can fail a run: an image that cannot be read is simply not shown. Thumbnails are
never written into ``report.json``; the HTML report embeds them (docs/formats.md), and an image
that passes drops them when it is scored. A JPEG is decoded at 1/2, 1/4 or 1/8 scale (what the
thumbnail needs): on a busy 2-core machine, 1.3 ms of harness CPU for a 1000 x 1000 JPEG, 18 ms
for a PNG of that size (inflated in full); a run that leaves no image costs a directory scan.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from arenabench.competition import OutputFormatError
from arenabench.eval.scoring.results import RunImage
from arenabench.limits import (
    MAX_IMAGE_SIDE_PX,
    MAX_RUN_IMAGE_BYTES,
    MAX_RUN_IMAGE_ENTRIES,
    MAX_RUN_IMAGE_PIXELS,
    MAX_RUN_IMAGES,
    RUN_IMAGE_THUMB_PX,
)

from .outputs import read_small

#: File name endings looked at (compared in lower case).
RUN_IMAGE_SUFFIXES: tuple[str, ...] = (".png", ".jpg", ".jpeg")
#: Names the harness gives its copy of the input image (``image`` + the dataset image's
#: extension; ``--image-name`` may name it otherwise): never shown as the run's own.
INPUT_COPY_NAMES: frozenset[str] = frozenset("image" + s for s in RUN_IMAGE_SUFFIXES)
#: JPEG quality of the thumbnails.
THUMB_JPEG_QUALITY = 80
#: Longest file name kept (characters; longer ones are cut with an ellipsis).
MAX_NAME_CHARS = 80


def _printable(name: str) -> str:
    """``name`` as text that any page can hold: undecodable bytes and control characters
    escaped, cut to :data:`MAX_NAME_CHARS`."""
    text = name.encode("utf-8", "backslashreplace").decode("utf-8")
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return text if len(text) <= MAX_NAME_CHARS else text[:MAX_NAME_CHARS - 3] + "..."


def _candidates(workdir: str) -> list[str]:
    """Names of the image files to try, sorted, from the first
    :data:`~arenabench.limits.MAX_RUN_IMAGE_ENTRIES` entries of ``workdir``."""
    names: list[str] = []
    try:
        with os.scandir(workdir) as it:
            for k, entry in enumerate(it):
                if k >= MAX_RUN_IMAGE_ENTRIES:
                    break
                name = entry.name
                if (name.lower().endswith(RUN_IMAGE_SUFFIXES) and name not in INPUT_COPY_NAMES
                        and entry.is_file(follow_symlinks=False)):
                    names.append(name)
    except OSError:
        return []
    return sorted(names)


_PNG_MAGIC, _JPEG_MAGIC = b"\x89PNG\r\n\x1a\n", b"\xff\xd8"
#: JPEG start-of-frame markers (they hold the image size); C4, C8 and CC are not frames.
_SOF_MARKERS = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}


def image_size(data: bytes) -> tuple[int, int] | None:
    """Width and height a PNG (``IHDR``) or JPEG (start-of-frame segment) header states, read
    without decoding anything; ``None`` for anything else or a malformed header."""
    if data.startswith(_PNG_MAGIC):
        if data[12:16] != b"IHDR" or len(data) < 24:
            return None
        return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    if not data.startswith(_JPEG_MAGIC):
        return None
    pos = 2
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            return None
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker == 0x01 or 0xD0 <= marker <= 0xD8:  # segments without a length
            pos += 2
            continue
        if marker in (0xD9, 0xDA):  # end of image, start of scan: no frame before them
            return None
        length = int.from_bytes(data[pos + 2:pos + 4], "big")
        if length < 2:
            return None
        if marker in _SOF_MARKERS:
            if pos + 9 > len(data):
                return None
            h = int.from_bytes(data[pos + 5:pos + 7], "big")
            return int.from_bytes(data[pos + 7:pos + 9], "big"), h
        pos += 2 + length
    return None


def _size_ok(data: bytes) -> bool:
    """Whether the header states a PNG or JPEG within the limits."""
    size = image_size(data)
    if size is None:
        return False
    w, h = size
    return 0 < w <= MAX_IMAGE_SIDE_PX and 0 < h <= MAX_IMAGE_SIDE_PX and \
        w * h <= MAX_RUN_IMAGE_PIXELS


def thumbnail_jpeg(data: bytes) -> RunImage | None:
    """A :class:`RunImage` (name left empty) of encoded PNG or JPEG bytes, or ``None`` when
    they are not a decodable image within the limits."""
    import cv2
    import numpy as np

    from arenabench.imageio import encode_jpeg

    if not _size_ok(data):
        return None
    w, h = image_size(data) or (0, 0)
    flag = cv2.IMREAD_COLOR
    if data.startswith(_JPEG_MAGIC):  # decoded at 1/2, 1/4 or 1/8 scale: much cheaper
        for factor, reduced in ((8, cv2.IMREAD_REDUCED_COLOR_8), (4, cv2.IMREAD_REDUCED_COLOR_4),
                                (2, cv2.IMREAD_REDUCED_COLOR_2)):
            if max(w, h) / factor >= RUN_IMAGE_THUMB_PX:
                flag = reduced
                break
    try:
        image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), flag)
    except cv2.error:
        return None
    if image is None or image.size == 0:
        return None
    scale = RUN_IMAGE_THUMB_PX / max(image.shape[:2])
    if scale < 1.0:
        ih, iw = image.shape[:2]
        image = cv2.resize(image, (max(1, round(iw * scale)), max(1, round(ih * scale))),
                           interpolation=cv2.INTER_AREA)
    return RunImage(name="", jpeg=encode_jpeg(image, quality=THUMB_JPEG_QUALITY),
                    width=w, height=h)


def collect_run_images(workdir: str | os.PathLike[str]) -> tuple[RunImage, ...]:
    """Thumbnails of the images a finished run left in ``workdir`` (see the module docstring
    for what is looked at and the bounds); empty when there are none."""
    kept: list[RunImage] = []
    for name in _candidates(os.fspath(workdir)):
        if len(kept) >= MAX_RUN_IMAGES:
            break
        try:
            data = read_small(Path(workdir, name), MAX_RUN_IMAGE_BYTES, name=name)
        except (OutputFormatError, OSError):
            continue
        thumb = thumbnail_jpeg(data)
        if thumb is not None:
            kept.append(replace(thumb, name=_printable(name)))
    return tuple(kept)
