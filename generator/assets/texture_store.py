"""Texture images kept by their content: what ``arena.texture_file`` names.

An arena texture given as an image file (``arena.texture = "image"``) is read once, checked
(a PNG or JPEG, at most :data:`~arenabench.limits.MAX_TEXTURE_BYTES` and
:data:`~arenabench.limits.MAX_IMAGE_SIDE_PX` a side) and named by its SHA-256: the parameter's
value, in a scene, a GT file and ``dataset.json``, is the **reference**
``textures/<sha256>.<png|jpg>``, which is also where a copy lies relative to the folder that
uses it (a dataset folder, a written preset file). Renderers find the bytes by the hash in the
user cache's ``textures/`` folder (:func:`arenabench.usercache.cache_dir`), where every
texture is put when it is first read, so every process on the machine (rendering workers, the
phase check re-rendering a GT scene, ``arenabench render``) finds it with nothing passed
along; a set copied to another machine brings its own ``textures/`` folder, which
:func:`import_folder` puts into that machine's cache. A file whose bytes do not have the hash
its name says is refused wherever it is read. Why both (docs/architecture.md, "Texture
images"): the copy in the set makes the set self-contained, the cache lets a GT scene be
re-rendered from the GT alone.
"""

from __future__ import annotations

import functools
import os
import re
from pathlib import Path

import cv2
import numpy as np

from arenabench.fileio import atomic_write_bytes, read_regular, sha256_bytes
from arenabench.imageio import ImageLoadError, declared_size_of, decode_image
from arenabench.limits import MAX_IMAGE_SIDE_PX, MAX_TEXTURE_BYTES

#: ``arena.texture`` of a floor drawn from an image file (``arena.texture_file``).
IMAGE_TEXTURE = "image"
#: Folder of the texture copies, in a dataset folder, beside a written preset file and in the
#: user cache.
TEXTURES_FOLDER = "textures"
#: A texture reference: ``textures/<sha256>.<ext>``.
REF_RE = re.compile(rf"{TEXTURES_FOLDER}/([0-9a-f]{{64}})\.(png|jpg)")
_MAGIC = {b"\x89PNG\r\n\x1a\n": "png", b"\xff\xd8\xff": "jpg"}


def is_ref(value: str) -> bool:
    """Whether ``value`` is a texture reference (``textures/<sha256>.png``)."""
    return isinstance(value, str) and REF_RE.fullmatch(value) is not None


def cache_folder() -> Path:
    """The user cache's texture folder (``<cache>/textures``)."""
    from arenabench.usercache import cache_dir

    return cache_dir() / TEXTURES_FOLDER


def _checked(data: bytes, where: str) -> str:
    """The reference of the image ``data`` (read from ``where``), after checking it is a
    whole PNG or JPEG of at most :data:`MAX_IMAGE_SIDE_PX` a side (the header is read before
    anything is decoded)."""
    ext = next((e for magic, e in _MAGIC.items() if data.startswith(magic)), None)
    if ext is None:
        raise ValueError(f"{where}: not a PNG or JPEG image")
    sides = declared_size_of(data)
    if sides is not None and (min(sides) < 1 or max(sides) > MAX_IMAGE_SIDE_PX):
        raise ValueError(f"{where}: its header declares {sides[0]} x {sides[1]} px (a side "
                         f"is 1 to {MAX_IMAGE_SIDE_PX} px)")
    try:
        decode_image(data, name=where)
    except ImageLoadError as exc:
        raise ValueError(str(exc)) from None
    return f"{TEXTURES_FOLDER}/{sha256_bytes(data)}.{ext}"


def _read(path: Path, where: str) -> bytes:
    try:
        return read_regular(path, limit=MAX_TEXTURE_BYTES)
    except OSError as exc:
        raise ValueError(f"{where}: cannot read it: {exc.strerror or exc}") from None


def import_texture(path: str | os.PathLike[str], *, where: str | None = None) -> str:
    """Read the image file ``path``, put it into the cache, return its reference.

    Parameters
    ----------
    path : path-like
        A PNG or JPEG file.
    where : str, keyword-only
        How messages name it (default: the path).

    Raises
    ------
    ValueError
        One line: unreadable, not a regular file, too large, not a PNG or JPEG, damaged.
    """
    p = Path(path)
    shown = where or str(p)
    data = _read(p, shown)
    ref = _checked(data, shown)
    add_bytes(ref, data)
    return ref


def add_bytes(ref: str, data: bytes) -> None:
    """Put a texture's bytes into the cache under ``ref`` (written once; checked).

    Raises
    ------
    ValueError
        When ``data`` is not the image ``ref`` names.
    """
    if _checked(data, ref) != ref:
        raise ValueError(f"{ref}: the bytes given are not this texture (their SHA-256 differs)")
    target = cache_folder() / Path(ref).name
    if not (target.is_file() and _hash_of(target) == _sha(ref)):
        atomic_write_bytes(target, data)


def _sha(ref: str) -> str:
    m = REF_RE.fullmatch(ref)
    if m is None:
        raise ValueError(f"arena.texture_file: {ref!r} is not a texture reference "
                         f"({TEXTURES_FOLDER}/<sha256>.png or .jpg)")
    return m.group(1)


def _hash_of(path: Path) -> str | None:
    try:
        return sha256_bytes(read_regular(path, limit=MAX_TEXTURE_BYTES))
    except OSError:
        return None


def texture_path(ref: str) -> Path:
    """The cached copy of the texture ``ref``.

    Raises
    ------
    ValueError
        One line when it is not in the cache (naming where to find it).
    """
    path = cache_folder() / Path(ref).name
    _sha(ref)
    if not path.is_file():
        raise ValueError(f"arena.texture_file={ref}: not in the texture cache {path.parent} "
                         f"(it is in the {TEXTURES_FOLDER}/ folder of the set or preset file "
                         "that uses it; give that set's dataset.json or that file once)")
    return path


def has(ref: str) -> bool:
    """Whether the cache (or this process, :func:`hold_texture`) holds the texture ``ref``."""
    return is_ref(ref) and (ref in _HELD or (cache_folder() / Path(ref).name).is_file())


#: Textures made in memory and held by this process only (:func:`hold_texture`).
_HELD: dict[str, bytes] = {}


def hold_texture(rgb: np.ndarray) -> str:
    """A texture made in memory ((H, W, 3) uint8 RGB, row 0 north), held by this process
    and not written to the cache (a trial texture, e.g. the twin's), until
    :func:`release_held`; returns its reference (of its PNG bytes)."""
    ok, buf = cv2.imencode(".png", cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR),
                           [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 RGB image
        raise ValueError("hold_texture: cannot encode the image as PNG")
    data = buf.tobytes()
    ref = _checked(data, "a texture made in memory")
    _HELD[ref] = data
    return ref


def keep_held(ref: str) -> str:
    """Put the held texture ``ref`` into the cache (so that other processes find it);
    returns ``ref``."""
    if ref in _HELD:
        add_bytes(ref, _HELD[ref])
    return ref


def release_held() -> None:
    """Forget the textures :func:`hold_texture` holds."""
    _HELD.clear()


def import_ref(ref: str, folder: Path, *, where: str) -> str:
    """The texture ``ref`` of a file in ``folder`` (``folder/ref``, a set's or a preset
    file's copy), put into the cache; or, when ``folder`` holds no copy, the cache's.

    Raises
    ------
    ValueError
        When neither holds it, or the copy is not the texture its name says.
    """
    copy = folder / ref
    if os.path.lexists(copy):
        data = _read(copy, where)
        if _checked(data, where) != ref:
            raise ValueError(f"{where}: its bytes are not the texture its name says (their "
                             "SHA-256 differs)")
        add_bytes(ref, data)
        return ref
    texture_path(ref)
    return ref


def import_folder(folder: str | os.PathLike[str]) -> list[str]:
    """Put every texture of a set's ``textures/`` folder into the cache (a set made on
    another machine); returns their references. Files not named as a reference are left
    alone.

    Raises
    ------
    ValueError
        For a copy that is not the texture its name says.
    """
    root = Path(folder)
    refs = []
    for path in sorted(root.iterdir()) if root.is_dir() else ():
        ref = f"{TEXTURES_FOLDER}/{path.name}"
        if is_ref(ref):  # a cached one is checked against its hash when it is read
            refs.append(ref if has(ref) else import_ref(ref, root.parent, where=str(path)))
    return refs


def export_texture(ref: str, folder: str | os.PathLike[str]) -> Path:
    """Copy the cached texture ``ref`` to ``folder/ref`` (a set's or a written preset
    file's ``textures/``), unless an equal copy is there; returns the copy's path."""
    target = Path(folder) / ref
    if target.is_file() and _hash_of(target) == _sha(ref):
        return target
    atomic_write_bytes(target, texture_bytes(ref))
    return target


def texture_bytes(ref: str) -> bytes:
    """The bytes of the cached (or held) texture ``ref`` (checked against its hash)."""
    if ref in _HELD:
        return _HELD[ref]
    data = _read(texture_path(ref), ref)
    if sha256_bytes(data) != _sha(ref):
        raise ValueError(f"{texture_path(ref)}: its bytes are not the texture its name says "
                         "(the cache copy was changed)")
    return data


@functools.lru_cache(maxsize=4)
def texture_rgb(ref: str) -> np.ndarray:
    """The texture ``ref`` as (H, W, 3) uint8 RGB, row 0 at the top (north), read-only."""
    bgr = decode_image(texture_bytes(ref), name=ref)  # 8-bit BGR (16-bit, grey, alpha too)
    rgb = np.ascontiguousarray(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    rgb.setflags(write=False)
    return rgb
