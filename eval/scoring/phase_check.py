"""The phase check: does a failure depend on where the box edges fall within a pixel?

For each failing image, the same scene is rendered again ``N`` times with every obstacle moved
by a sub-pixel amount (phases spread over one image pixel in x and y, each box at its own
phase), its ground truth
computed analytically as always, and the pipeline run again on each (docs/phase-check.md).
``k`` of the ``N`` phases pass:

- ``k = 0``: a **robust** failure (the method is wrong on this scene);
- ``k > 0``: a **phase-dependent** failure (:data:`PHASE_DEPENDENT_MEANING`).

A passing image is never re-run, and nothing of the generator is imported while nothing
fails. The pipeline is the run's own adapter (an external command keeps its limits and
sandbox).
"""

from __future__ import annotations

import argparse
import math
import shutil
import tempfile
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from arenabench.gtrecord import GroundTruth
from arenabench.interrupts import checkpoint

from .metrics import score_sample
from .results import (
    CATEGORIES,
    SCORING_FAILURES,
    HarnessError,
    ImageResult,
    PhaseResult,
    Prediction,
)

#: Phases a check renders by default.
DEFAULT_PHASES = 8
#: Largest ``--phase-check N``.
MAX_PHASES = 64
#: Presets whose runs check failures' phases unless told ``--phase-check off``: the
#: hidden-test twin, whose renderer blends box edges only at some sub-pixel phases.
DEFAULT_ON_PRESETS = frozenset({"eyrc"})
#: The one sentence every report prints beside the rates.
PHASE_DEPENDENT_MEANING = (
    "phase-dependent: passes at some sub-pixel positions of the boxes and fails at others: on "
    "the hidden tests it would have depended on luck"
)
#: The failure categories the check re-runs: answers that scoring found wrong (``wrong_count``,
#: ``area_off``), the only failures a box's sub-pixel position can turn into a pass. The
#: others stay unchecked: the program failed (``crash``, ``timeout``, ``limit``) or gave no
#: answer (``bad_output``), and ``markers_not_found`` sees the same marker pixels at every
#: phase (only the boxes move; the marker squares are byte-identical), so re-running any of
#: them N times would only cost.
CHECKED_CATEGORIES = frozenset(SCORING_FAILURES)


# ------------------------------------------------------------------------------ the option

def parse_phase_check(text: str) -> str | int:
    """``--phase-check`` value: ``"auto"``, ``0`` (``off``) or a number of phases.

    Raises
    ------
    argparse.ArgumentTypeError
        For anything else (argparse turns it into a one-line usage error, exit 2).
    """
    word = str(text).strip().lower()
    if word == "off":
        return 0
    if word == "auto":
        return "auto"
    try:
        n = int(word)
    except ValueError:
        n = -1
    if not 1 <= n <= MAX_PHASES:
        raise argparse.ArgumentTypeError(
            f"must be a number of phases in [1, {MAX_PHASES}], 'off' or 'auto', got {text!r}")
    return n


def add_phase_check_argument(parser: argparse.ArgumentParser) -> None:
    """The ``--phase-check N|off|auto`` option of ``eval``, ``sweep``, ``grade`` and
    ``check``."""
    parser.add_argument(
        "--phase-check", type=parse_phase_check, default="auto", metavar="N|off|auto",
        help=f"re-render each failing image's scene with the boxes moved by N sub-pixel "
        f"amounts and re-run the pipeline: a failure that passes at none is 'robust', one that "
        f"passes at some 'phase-dependent' (luck). auto (default): {DEFAULT_PHASES} phases on "
        f"{', '.join(sorted(DEFAULT_ON_PRESETS))} scenes, off otherwise",
    )


def resolve_phases(value: str | int, presets: Sequence[str]) -> int:
    """Phases to check for ``--phase-check value`` on scenes of ``presets`` (0 = off)."""
    if value == "auto":
        return DEFAULT_PHASES if any(p in DEFAULT_ON_PRESETS for p in presets) else 0
    return int(value)


# ------------------------------------------------------------------------------ the phases

def phase_offsets(n: int) -> list[tuple[float, float]]:
    """``n`` sub-pixel offsets (dx, dy) in [0, 1) px, spread evenly over the pixel.

    A shifted Hammersley set: ``dx = (i + 1/2) / n`` and ``dy`` the base-2 radical inverse of
    ``i`` shifted by ``1/(2n)``, so each row and each column of an ``n``-cell grid holds one
    offset and none is the unshifted scene.
    """
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n!r}")
    out = []
    for i in range(n):
        inv, f, k = 0.0, 0.5, i
        while k:
            inv += f * (k & 1)
            k >>= 1
            f /= 2
        out.append(((i + 0.5) / n, (inv + 0.5 / n) % 1.0))
    return out


#: Per-box rotation of the offsets (box ``j`` adds ``j`` times these, modulo 1 px): irrational
#: steps, so the boxes of one scene land at unrelated phases, as on an independent image.
BOX_STEP = ((5 ** 0.5 - 1) / 2, 2 ** 0.5 - 1)


def box_offsets(offset: tuple[float, float], n_boxes: int) -> list[tuple[float, float]]:
    """The offsets of a scene's boxes at one phase: box ``j`` gets ``offset + j * BOX_STEP``
    modulo 1 px, so over the phases every box sweeps its pixel evenly and the boxes' phases
    are unrelated (a hidden-test image gives each box its own luck)."""
    dx, dy = offset
    return [((dx + j * BOX_STEP[0]) % 1.0, (dy + j * BOX_STEP[1]) % 1.0)
            for j in range(n_boxes)]


def shifted_scene(scene: Any, offsets: Sequence[tuple[float, float]]) -> Any:
    """``scene`` with obstacle ``j`` moved so that the centre of its top face moves by
    ``offsets[j]`` = (dx, dy) image px (pinhole camera; the move is found on the top face's
    plane).

    Parameters
    ----------
    scene : arenabench.generator.scene.Scene
        The scene.
    offsets : sequence of (float, float)
        Image px, one pair per obstacle.
    """
    from arenabench.generator import camera as cam

    if len(offsets) != len(scene.obstacles):
        raise ValueError(f"need one offset per obstacle ({len(scene.obstacles)}), got "
                         f"{len(offsets)}")
    K = cam.intrinsics(scene.camera)
    pose = cam.world_from_camera(scene.camera)
    r, c = pose[:3, :3], pose[:3, 3]
    k_inv = np.linalg.inv(K)
    moved = []
    for ob, (dx, dy) in zip(scene.obstacles, offsets, strict=True):
        top = np.array([*ob.center_m, ob.height_m])
        uv = cam.project(top[None, :], K, pose)[0]
        ray = r @ (k_inv @ np.array([uv[0] + dx, uv[1] + dy, 1.0]))
        t = (ob.height_m - c[2]) / ray[2]
        hit = c + t * ray
        moved.append(replace(ob, center_m=(float(hit[0]), float(hit[1]))))
    return replace(scene, obstacles=tuple(moved))


@dataclass(frozen=True)
class PhaseImage:
    """One re-rendered phase: its image file and ground truth."""

    path: Path
    gt: GroundTruth


def _encode(bgr: np.ndarray, suffix: str, *, preset: str | None,
            quality: int | None = None) -> bytes:
    """Encode a phase image as the dataset's writer encodes the scene's preset (PNG, or JPEG at
    ``quality``: the original image's, else the built-in preset's ``output.jpeg_quality``)."""
    from arenabench.imageio import IMAGE_EXTENSIONS, encode_image

    ext = suffix.lower().lstrip(".")
    image_format = next((f for f, e in IMAGE_EXTENSIONS.items() if ext in (e, f)), None)
    if image_format is None:
        raise ValueError(f"cannot encode an image as {suffix!r}")
    if quality is not None:
        return encode_image(bgr, image_format=image_format, jpeg_quality=quality)
    quality = 95
    if image_format == "jpeg" and preset:
        from arenabench.generator.presets import get_preset

        try:
            quality = int(get_preset(preset).get("output.jpeg_quality", quality))
        except ValueError:  # a preset this version does not know: cv2.imwrite's default
            pass
    return encode_image(bgr, image_format=image_format, jpeg_quality=quality)


def render_phases(gt: GroundTruth, *, phases: int, folder: Path, suffix: str = ".png",
                  renderer: Any = None, jpeg_quality: int | None = None
                  ) -> Iterator[PhaseImage]:
    """Render the scene of ``gt`` at ``phases`` sub-pixel offsets into ``folder``
    (:func:`phase_offsets`, each box rotated by :func:`box_offsets`).

    The image goes through the scene's own degradations (GT ``params``, the scene's noise
    stream) like the original; each phase's GT is computed from its moved scene.

    Parameters
    ----------
    gt : GroundTruth
        The failing image's ground truth (needs ``scene``).
    phases : int, keyword-only
        Number of offsets (:func:`phase_offsets`).
    folder : Path, keyword-only
        Where the images are written (``phase-NN`` + ``suffix``).
    suffix : str, keyword-only
        Image file type, that of the original image.
    renderer : SceneRenderer, keyword-only
        Default: this thread's :func:`arenabench.generator.make.worker_renderer`.
    jpeg_quality : int, keyword-only
        The original JPEG's quality (:func:`original_jpeg_quality`); default: the built-in
        preset's.
    """
    import cv2

    from arenabench.fileio import rounded
    from arenabench.generator.degrade import Degradations, apply_degradations
    from arenabench.generator.make import degrade_rng, ground_truth_record, worker_renderer
    from arenabench.generator.scene import Scene

    if gt.scene is None:
        raise ValueError(f"GT {gt.id!r} holds no scene: cannot re-render it")
    scene = Scene.from_dict(gt.to_dict()["scene"])
    renderer = renderer or worker_renderer()
    params = dict(gt.params or {})
    degradations = Degradations.from_params(params)
    frame = None
    if gt.frame is not None and gt.frame.size:
        from arenabench.frame import FrameSpec

        frame = FrameSpec(size=int(gt.frame.size[0]), corners=gt.frame.corners or "inner")
    sampled = {k: v for k, v in params.items() if not k.startswith("derived.")}
    for i, offset in enumerate(phase_offsets(phases)):
        offsets = box_offsets(offset, len(scene.obstacles))
        moved = Scene.from_dict(rounded(shifted_scene(scene, offsets).to_dict()))
        rgb = renderer.render(moved).rgb
        if not degradations.is_neutral:
            rgb = apply_degradations(rgb, degradations, degrade_rng(gt.seed, gt.index))
        path = folder / f"phase-{i:02d}{suffix}"
        path.write_bytes(_encode(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), suffix,
                                 preset=gt.preset, quality=jpeg_quality))
        record = ground_truth_record(moved, sid=gt.id, preset=gt.preset, seed=gt.seed,
                                     index=gt.index, params=sampled, frame=frame)
        yield PhaseImage(path=path, gt=record)


# ------------------------------------------------------------------------------ the check

def original_jpeg_quality(image: str | Path) -> int | None:
    """The quality the JPEG file ``image`` was written at (its tables,
    :func:`arenabench.imageio.jpeg_quality`); ``None`` for another file or none found."""
    from arenabench.fileio import open_regular
    from arenabench.imageio import ImageLoadError, jpeg_quality

    if Path(image).suffix.lower() not in (".jpg", ".jpeg"):
        return None
    try:
        with open_regular(image) as fh:
            head = fh.read(1 << 20)  # the tables come before the scan
        return jpeg_quality(head)
    except (OSError, ImageLoadError):
        return None


def checked(result: ImageResult) -> bool:
    """Whether the phase check re-runs this image: a failure of a category in
    :data:`CHECKED_CATEGORIES`."""
    return not result.passed and result.category in CHECKED_CATEGORIES


def unchecked_text() -> str:
    """The failure categories the check leaves alone, as reports name them
    (``"markers_not_found, crash, timeout, limit, bad_output"``)."""
    return ", ".join(c for c in CATEGORIES if c not in CHECKED_CATEGORIES)


def check_phases(
    results: Sequence[ImageResult],
    gts: Sequence[GroundTruth],
    run: Callable[[Path], Prediction],
    *,
    phases: int,
    tolerance: float,
    area_reference: str,
    workers: int = 1,
    renderer: Any = None,
    on_image: Callable[[], None] | None = None,
    stop: Callable[[], None] | None = None,
) -> list[ImageResult]:
    """``results`` with :class:`PhaseResult` added to each failing image (``phase``).

    Parameters
    ----------
    results : sequence of ImageResult
        A run's scored images.
    gts : sequence of GroundTruth
        Their ground truths (same order).
    run : callable
        The run's pipeline: image path -> :class:`Prediction` (never raises for the
        pipeline's own failures).
    phases : int, keyword-only
        Phases per failing image; 0 returns ``results`` unchanged.
    tolerance, area_reference : keyword-only
        The run's scoring settings.
    workers : int, keyword-only
        Pipeline runs in parallel (renders happen in the calling thread, one after another).
    renderer : SceneRenderer, keyword-only
        Default: this thread's reused renderer.
    on_image : callable, keyword-only
        Called after each failing image is checked (progress).
    stop : callable, keyword-only
        The pipeline's ``stop`` (kills its running runs): called when the check is cut short
        (a stop signal), before the check waits for its runs, so that it ends at once rather
        than after the runs' timeouts.

    Returns
    -------
    list of ImageResult
        Passing images untouched; failing images with ``phase`` set when
        :func:`checked` (any other failure keeps ``phase=None``).
    """
    from arenabench.eval.datasets.reader import DatasetItem

    if len(results) != len(gts):
        raise ValueError(f"results and gts must have the same length, got {len(results)} "
                         f"and {len(gts)}")
    failing = [i for i, r in enumerate(results) if checked(r) and gts[i].scene is not None]
    out = list(results)
    if phases < 1 or not failing:
        return out
    from arenabench.eval.runs import owned_dir_prefix

    tmp = tempfile.mkdtemp(prefix=owned_dir_prefix("arenabench-phase-"))
    pool = ThreadPoolExecutor(max_workers=max(1, workers), thread_name_prefix="arenabench-phase")
    try:
        try:
            for i in failing:
                checkpoint()  # a stop signal a library swallowed
                folder = Path(tmp, f"{i:06d}")
                folder.mkdir()
                suffix = Path(results[i].image).suffix or ".png"
                pending = []
                try:
                    for image in render_phases(gts[i], phases=phases, folder=folder,
                                               suffix=suffix, renderer=renderer,
                                               jpeg_quality=original_jpeg_quality(
                                                   results[i].image)):
                        pending.append((image, pool.submit(_safe_run, run, image.path)))
                except Exception as exc:  # a scene that cannot be re-rendered stays unchecked
                    _warn(f"phase check of {results[i].id} skipped: {type(exc).__name__}: {exc}")
                    for _, fut in pending:
                        fut.cancel()
                    pending = []
                passes = 0
                for image, fut in pending:
                    if fut.cancelled():
                        continue
                    item = DatasetItem(id=results[i].id, image_path=image.path,
                                       gt_path=image.path, gt=image.gt)
                    scored = score_sample(item, fut.result(), tolerance=tolerance,
                                          area_reference=area_reference)
                    passes += scored.passed
                if pending:
                    out[i] = replace(results[i], phase=PhaseResult(passes=passes, n=phases))
                shutil.rmtree(folder, ignore_errors=True)
                if on_image is not None:
                    on_image()
        except BaseException:  # a stop signal: end the runs, then wait for their threads
            if stop is not None:
                stop()
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def _warn(message: str) -> None:
    import sys

    print(f"arenabench: warning: {message}", file=sys.stderr)


def _safe_run(run: Callable[[Path], Prediction], path: Path) -> Prediction:
    try:
        return run(path)
    except HarnessError:  # the harness's own failure: the check stops, nothing is scored
        raise
    except Exception as exc:  # the harness never dies from a bad pipeline
        return Prediction(status="crash", message=f"{type(exc).__name__}: {exc}")


# ------------------------------------------------------------------------------ summaries

def phase_summary(results: Sequence[ImageResult]) -> dict[str, Any]:
    """The phase-check keys of a report's summary.

    Returns
    -------
    dict
        ``robust_failure_rate`` and ``phase_dependent_failure_rate`` (fractions of all
        images; ``None`` when no image was phase-checked) and ``phase_check``: ``phases``
        (N), ``checked``, ``robust``, ``phase_dependent``, ``unchecked`` (failing images not
        checked: the categories outside :data:`CHECKED_CATEGORIES`) (image counts),
        ``meaning`` (one sentence); ``None`` when no image was phase-checked.
    """
    checked = [r.phase for r in results if r.phase is not None]
    if not checked:
        return {"robust_failure_rate": None, "phase_dependent_failure_rate": None,
                "phase_check": None}
    n = len(results)
    robust = sum(1 for p in checked if p.label == "robust")
    dependent = len(checked) - robust
    return {
        "robust_failure_rate": robust / n,
        "phase_dependent_failure_rate": dependent / n,
        "phase_check": {"phases": max(p.n for p in checked), "checked": len(checked),
                        "robust": robust, "phase_dependent": dependent,
                        "unchecked": sum(1 for r in results
                                         if not r.passed and r.phase is None),
                        "meaning": PHASE_DEPENDENT_MEANING},
    }


def rate_text(value: float | None) -> str:
    """A rate as the reports print it (``-`` when the phase check did not run)."""
    return "-" if value is None or not math.isfinite(value) else f"{100 * value:.1f} %"
