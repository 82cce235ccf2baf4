"""One manifest entry checked: its paths stay in the dataset folder, its hashes match, its
image is not damaged and its ground truth follows the ``arenabench.gt/1`` schema. Used by the
one-process reader (:mod:`.reader`) and the parallel check (:mod:`.check`) alike."""

from __future__ import annotations

import errno
import json
import os
import re
from pathlib import Path
from typing import Any

from arenabench.fileio import read_regular, sha256_bytes, sha256_file
from arenabench.imageio import image_file_problem
from arenabench.schemas import gt_problem


class DatasetError(ValueError):
    """A dataset is missing or malformed; the message names the file and field."""


_SHA256 = re.compile(r"[0-9a-f]{64}")


def _is_sha256(value: Any) -> bool:
    return isinstance(value, str) and _SHA256.fullmatch(value) is not None


def path_error(path: Path, what: str) -> DatasetError:
    """The :class:`DatasetError` ``"<path>: <what>"``."""
    return DatasetError(f"{path}: {what}")


def validate_gt(gt: Any, path: Path) -> None:
    """Check a parsed GT record against the ``arenabench.gt/1`` JSON Schema (shipped in
    :mod:`arenabench.schemas`) and that every number in it is finite.

    Raises
    ------
    DatasetError
        One line naming ``path``, the field and the problem, e.g.
        ``gt/000003.json: area.visible_px: nan is not a finite number``.
    """
    problem = gt_problem(gt)
    if problem is not None:
        raise path_error(path, problem)


def os_problem(exc: OSError | RuntimeError) -> str:
    """A file system error in words: ``cannot read (Permission denied)``, ``a symbolic link
    loop``."""
    if isinstance(exc, RuntimeError) or exc.errno == errno.ELOOP:
        return "a symbolic link loop"
    return f"cannot read ({exc.strerror or exc})"


def gt_facts(gt: dict[str, Any], area_keys: tuple[str, ...]) -> tuple[str, tuple[str, ...], Any]:
    """What :class:`DatasetFacts` keeps of one valid GT record: its preset (``""`` for none),
    the keys of ``area_keys`` its area lacks, and its ``seed`` (``None`` for none)."""
    area = gt["area"]
    return (gt.get("preset") or "", tuple(k for k in area_keys if area.get(k) is None),
            gt.get("seed"))


def _inside(base: Path, rel: str, dirs: dict[str, Path]) -> bool:
    """Whether ``rel`` names a path inside the resolved folder ``base``, symbolic links
    followed; ``dirs`` caches the resolved folders (one ``lstat`` per file, not per
    component, for the common ``images/NNNNNN.png``)."""
    if os.path.isabs(rel):
        return False
    folder, _, name = rel.rpartition("/")
    if name in ("", ".", "..") or any(p in ("", ".", "..") for p in folder.split("/") if folder):
        return (base / rel).resolve().is_relative_to(base)
    real = dirs.get(folder)
    if real is None:
        real = dirs[folder] = (base / folder).resolve()
    path = real / name
    if path.is_symlink():
        return path.resolve().is_relative_to(base)
    return real.is_relative_to(base)


def checked_entry(entry: dict[str, Any], where: str, *, base: Path, shown: Path,
                   verify: bool, dirs: dict[str, Path]) -> dict[str, Any] | str:
    """:func:`_checked_files`; a file of the entry that cannot be read (a folder without
    permission, a symbolic link loop) is a :class:`DatasetError` naming the manifest line."""
    try:
        return _checked_files(entry, where, base=base, shown=shown, verify=verify, dirs=dirs)
    except (OSError, RuntimeError) as exc:  # RuntimeError: Path.resolve of a link loop
        what = getattr(exc, "filename", None)
        raise DatasetError(f"{where}: {f'{what}: ' if what else ''}{os_problem(exc)}") from None


def _check_paths(entry: dict[str, Any], where: str, *, base: Path, shown: Path,
                 verify: bool, dirs: dict[str, Path]) -> None:
    """The entry's hash fields (with ``verify``), and its two files: inside the dataset's
    folder, and regular files."""
    if verify:
        for key in ("image_sha256", "gt_sha256"):
            if not _is_sha256(entry.get(key)):
                raise DatasetError(
                    f"{where}: field {key!r} missing or not a SHA-256 hex digest "
                    "(--no-verify skips the check)"
                )
    for key in ("image", "gt"):
        rel = entry[key]
        if not _inside(base, rel, dirs):
            raise DatasetError(f"{where}: {key} path {rel!r} leaves the dataset folder "
                               f"{shown} (a dataset is a closed folder)")
    for what, key in (("image", "image"), ("ground-truth", "gt")):
        path = base / entry[key]
        if not path.is_file():
            why = "is not a regular file" if path.exists() else "does not exist"
            raise DatasetError(f"{where}: {what} file {shown / entry[key]} {why}")


def _check_hashes(entry: dict[str, Any], gt_bytes: bytes, image_path: Path, *,
                  shown_image: Path, shown_gt: Path) -> None:
    """The GT's bytes and the image file against the manifest's SHA-256 values."""
    if sha256_bytes(gt_bytes) != entry["gt_sha256"]:
        raise path_error(shown_gt, "content does not match gt_sha256 in manifest.jsonl "
                         "(corrupt or replaced; --no-verify skips the check)")
    try:
        digest = sha256_file(image_path)
    except OSError as exc:
        raise path_error(shown_image, f"cannot read ({exc.strerror or exc})") from None
    if digest != entry["image_sha256"]:
        raise path_error(shown_image, "content does not match image_sha256 in manifest.jsonl "
                         "(truncated, corrupt or replaced; --no-verify skips the check)")


def _parsed_gt(gt_bytes: bytes, shown_gt: Path) -> Any:
    """The GT file's JSON (one line naming the file when it is not JSON)."""
    try:
        return json.loads(gt_bytes.decode("utf-8"))
    except UnicodeDecodeError:
        raise path_error(shown_gt, "not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise path_error(shown_gt, f"not JSON ({exc.msg} at line {exc.lineno})") from None
    except RecursionError:
        raise path_error(shown_gt, "not JSON (nested too deeply)") from None


def _checked_files(entry: dict[str, Any], where: str, *, base: Path, shown: Path,
                   verify: bool, dirs: dict[str, Path]) -> dict[str, Any] | str:
    """Check one manifest entry's files (closed folder, hashes, damage, GT schema): the
    parsed GT, or why the image is damaged.

    Raises
    ------
    DatasetError
        For anything else wrong with the entry.
    """
    _check_paths(entry, where, base=base, shown=shown, verify=verify, dirs=dirs)
    image_path, gt_path = base / entry["image"], base / entry["gt"]
    shown_image, shown_gt = shown / entry["image"], shown / entry["gt"]
    try:
        gt_bytes = read_regular(gt_path)
    except OSError as exc:
        raise path_error(shown_gt, f"cannot read ({exc.strerror or exc})") from None
    if verify:
        _check_hashes(entry, gt_bytes, image_path, shown_image=shown_image, shown_gt=shown_gt)
    damage = image_file_problem(image_path)
    if damage is not None:
        return damage
    gt = _parsed_gt(gt_bytes, shown_gt)
    validate_gt(gt, shown_gt)
    return gt
