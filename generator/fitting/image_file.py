"""The image file: its format, and for a JPEG the quality and chroma subsampling read from the
file's own tables (:func:`arenabench.imageio.jpeg_settings`; nothing is decoded for them)."""

from __future__ import annotations

from dataclasses import dataclass

from arenabench.imageio import decode_image, encode_image, jpeg_quality, jpeg_settings

_PNG = b"\x89PNG\r\n\x1a\n"
_JPEG = b"\xff\xd8\xff"


@dataclass(frozen=True)
class FileFacts:
    """How the image was written.

    Attributes
    ----------
    format : str
        ``"png"``, ``"jpeg"`` or another format's name (written as PNG by the twin).
    jpeg_quality : int or None
        The JPEG's quality (libjpeg's scale).
    jpeg_subsampling : str or None
        ``"420"``, ``"422"`` or ``"444"``.
    exact : bool
        Whether the JPEG's tables are exactly libjpeg's at that quality (what ``cv2.imwrite``
        writes); otherwise the nearest quality.
    """

    format: str
    jpeg_quality: int | None = None
    jpeg_subsampling: str | None = None
    exact: bool = True

    @property
    def output_format(self) -> str:
        """The ``output.format`` that writes such files."""
        return "jpeg" if self.format == "jpeg" else "png"


def read_file_facts(data: bytes, *, name: str = "image") -> FileFacts:
    """The format of ``data`` and, for a JPEG, its quality and subsampling."""
    if data.startswith(_JPEG):
        settings = jpeg_settings(data, name=name)
        return FileFacts("jpeg", settings.quality, settings.subsampling,
                         exact=jpeg_quality(data, name=name) is not None)
    if data.startswith(_PNG):
        return FileFacts("png")
    return FileFacts("other")


def as_written(bgr, facts: FileFacts):
    """``bgr`` round-tripped through the file the image was (a JPEG at its quality and
    subsampling; a PNG as it is): how the twin's images are written."""
    if facts.format != "jpeg":
        return bgr
    return decode_image(encode_image(bgr, image_format="jpeg", jpeg_quality=facts.jpeg_quality,
                                     jpeg_subsampling=facts.jpeg_subsampling))
