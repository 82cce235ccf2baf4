"""The phase check: does a failure depend on where the box edges fall within a pixel, or on
what the evidence behind the preset leaves open?

For each failing image, the same scene is rendered again ``N`` times with every obstacle moved
by a sub-pixel amount (phases spread over one image pixel in x and y, each box at its own
phase), through the generator's one image recipe
(:func:`arenabench.generator.dataset.make.scene_image`: the set's degradations, encoding and GT),
and
the pipeline run again on each (docs/phase-check.md). When no phase passes, the same is done
under each other value the preset's open parameters allow (:func:`open_variants`). A run that
does not complete (:data:`NOT_COMPLETED`, a harness error) is not a failed run; over the
completed runs the image is (:data:`arenabench.eval.scoring.results.PHASE_LABELS`):

- **phase-dependent** when some phase of its own scene passes
  (:data:`~arenabench.eval.scoring.phase_summary.PHASE_DEPENDENT_MEANING`);
- **depends on open** when only another value of an open parameter passes;
- **robust** when no completed run passes (the method is wrong on this scene);
- **unchecked** when no run completed.

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
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from arenabench.gtrecord import GroundTruth
from arenabench.interrupts import checkpoint, result_of

from .scoring.metrics import score_sample
from .scoring.results import (
    CATEGORIES,
    SCORING_FAILURES,
    HarnessError,
    ImageResult,
    PhaseResult,
    Prediction,
    VariantResult,
)

#: Phases a check renders by default.
DEFAULT_PHASES = 8
#: Largest ``--phase-check N``.
MAX_PHASES = 64
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
        f"amounts and re-run the pipeline: a failure that passes at some is 'phase-dependent' "
        f"(luck); one that passes at none is re-run under the other values of the preset's "
        f"open parameters: 'depends-on-open' when one passes, else 'robust'; runs that crash, "
        f"time out or hit a limit do not count. auto (default): {DEFAULT_PHASES} phases on "
        f"scenes of a twin (a preset that declares open parameters, eyrc among them), off "
        f"otherwise",
    )


def declares_open(preset: Any) -> bool:
    """Whether ``preset`` is a twin: a preset that declares parameters its evidence leaves
    open (``preset``: a :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`, or
    the
    name a GT file records, which counts only when it names a built-in preset).

    A twin's scenes are the hidden tests' look-alikes: a failure there is worth telling apart
    as robust, phase-dependent or depending on what is open, so ``--phase-check auto`` is on
    for them (``eyrc`` declares its unseen east and west fills open).
    """
    from arenabench.generator.parameters.presets import builtin_preset, preset_names

    if isinstance(preset, str):
        if preset not in preset_names():
            return False
        preset = builtin_preset(preset)
    return bool(getattr(preset, "open", None))


def resolve_phases(value: str | int, presets: Sequence[Any]) -> int:
    """Phases to check for ``--phase-check value`` on scenes of ``presets`` (0 = off):
    ``auto`` is :data:`DEFAULT_PHASES` when one of them is a twin (:func:`declares_open`)."""
    if value == "auto":
        return DEFAULT_PHASES if any(declares_open(p) for p in presets) else 0
    return int(value)


def set_presets(data: Any) -> list[Any]:
    """The presets a set's scenes were drawn from, for :func:`resolve_phases`: the definition
    its ``dataset.json`` records, else the names its GT files record."""
    source = dataset_scene_source(data.root, None if data.meta is None else data.meta.doc,
                                  warn=False)
    return [source.preset] if source is not None else list(data.presets())


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
    scene : arenabench.generator.model.scene.Scene
        The scene.
    offsets : sequence of (float, float)
        Image px, one pair per obstacle.
    """
    from arenabench.generator.model import camera as cam

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


@dataclass(frozen=True)
class SceneSource:
    """What re-making a set's scenes needs: the preset they were drawn from and the ``--set``
    values (a set's ``dataset.json``: :func:`dataset_scene_source`; a sweep point's task).

    Attributes
    ----------
    preset : ResolvedPreset
        The preset (its ``open`` entries are the parameters the evidence leaves open).
    overrides : dict
        The ``--set`` values the scenes were drawn with.
    """

    preset: Any
    overrides: dict[str, Any] = field(default_factory=dict)

    @property
    def open(self) -> dict[str, Any]:
        """The preset's open parameters: name -> OpenParam."""
        return dict(getattr(self.preset, "open", None) or {})

    def output(self) -> Any:
        """How the set's images are encoded
        (:class:`arenabench.generator.dataset.make.ImageFormat`)."""
        from arenabench.generator.dataset.make import ImageFormat

        return ImageFormat.of_preset(self.preset, self.overrides)

    def sample(self, gt: GroundTruth, change: dict[str, Any] | None = None) -> Any:
        """Scene ``gt.index`` of the run drawn again (``change``: open parameters set to
        other values; every other draw is the same, each parameter having its own random
        stream): a :class:`~arenabench.generator.model.sampler.SampledScene`."""
        from arenabench.generator.model.sampler import sample_scene

        return sample_scene(self.preset, seed=gt.seed, index=gt.index,
                            overrides={**self.overrides, **(change or {})})

    def reproduces(self, gt: GroundTruth) -> bool:
        """Whether drawing scene ``gt.index`` again gives ``gt``'s scene (then its open
        parameters can be varied)."""
        from arenabench.fileio import rounded

        try:
            again = self.sample(gt)
        except Exception:
            return False
        return rounded(again.scene.to_dict()) == gt.to_dict()["scene"]


def dataset_scene_source(root: str | Path, doc: Any, *, warn: bool = True
                         ) -> SceneSource | None:
    """The :class:`SceneSource` of a set from its ``dataset.json`` content ``doc``
    (``preset_definition`` and ``args.overrides``); ``None`` when it records none, or one
    that cannot be read again (said on stderr when ``warn``)."""
    from arenabench.generator.parameters.param_values import parse_override
    from arenabench.generator.parameters.preset_files import preset_from_document

    if not isinstance(doc, dict) or not isinstance(doc.get("preset_definition"), dict):
        return None
    path = Path(root) / "dataset.json"
    try:
        preset = preset_from_document(doc["preset_definition"], where=str(path),
                                      base=Path(root), source=path)
        stored = (doc.get("args") or {}).get("overrides") or {}
        overrides = dict(parse_override(f"{k}={v}") for k, v in stored.items())
    except ValueError as exc:
        if warn:
            _warn(f"phase check: {path}: its preset cannot be read again ({exc}): open "
                  "parameters are not varied")
        return None
    return SceneSource(preset=preset, overrides=overrides)


@dataclass(frozen=True)
class Variant:
    """One open parameter set to another value the evidence allows (``param=value``), with
    the parameters that move with it (``also``: the preset's ``moves_with``)."""

    param: str
    value: Any
    also: tuple[tuple[str, Any], ...] = ()

    def settings(self) -> dict[str, Any]:
        """Every parameter the variant sets: ``param`` and those moving with it."""
        return {self.param: self.value, **dict(self.also)}

    def text(self) -> str:
        """``lighting.east_fill=0.3``; ``camera.fov_deg=68.34 (camera.altitude_m=3.188)``."""
        def one(name: str, value: Any) -> str:
            return f"{name}={value:g}" if isinstance(value, float) else f"{name}={value}"

        more = ", ".join(one(k, v) for k, v in self.also)
        return one(self.param, self.value) + (f" ({more})" if more else "")


def open_variants(source: SceneSource) -> list[Variant]:
    """The other values the preset's open parameters allow, one parameter at a time (with
    those that move with it): a range's ends, or each listed value, other than the preset's
    own value. The same for every scene of the set: a parameter the preset holds fixed has
    the same value in each.

    A parameter the preset draws per scene (a range: a twin's box count, sizes and yaw, open
    because one image is one draw) is not varied: another draw is another scene, with other
    boxes and another answer, which the set's other scenes already are; it says nothing of
    what the example could not show about this one.

    A parameter that moves with another (an entry's ``moves_with``: the image pins their
    trade, not either one) is not varied on its own: the other's variants set it too, to its
    value at the same end.
    """
    from arenabench.generator.parameters.params import PARAMETERS, Range
    from arenabench.generator.parameters.presets import resolve

    if not source.open:
        return []
    params = resolve(source.preset, source.overrides)
    companions = {c for entry in source.open.values() for c, _ in entry.moves_with}
    out = []
    for name, entry in source.open.items():
        own = params.get(name)
        if isinstance(own, Range) or name in companions:  # drawn per scene; moved by another
            continue
        points = ([entry.range.lo, entry.range.hi] if entry.range is not None
                  else list(entry.values or ()))
        tried: dict[Any, Any] = {}  # each value tried -> the point whose companions it takes
        for point in points:
            rounded = entry.range is not None and PARAMETERS[name].kind == "int"
            tried.setdefault(round(point) if rounded else point, point)
        for value, point in tried.items():
            same = (isinstance(value, (int, float)) and isinstance(own, (int, float))
                    and math.isclose(float(value), float(own), abs_tol=1e-9))
            if not same and value != own:
                out.append(Variant(name, value, tuple(sorted(entry.at(point).items()))))
    return out


def render_phases(gt: GroundTruth, *, phases: int, folder: Path, output: Any = None,
                  renderer: Any = None, scene: Any = None,
                  params: dict[str, Any] | None = None,
                  offsets: Sequence[tuple[float, float]] | None = None,
                  ) -> Iterator[PhaseImage]:
    """Render the scene of ``gt`` at ``phases`` sub-pixel offsets into ``folder``
    (:func:`phase_offsets`, each box rotated by :func:`box_offsets`).

    Each image is made by the generator's one image recipe
    (:func:`arenabench.generator.dataset.make.scene_image`: render, the scene's own degradations
    with
    its noise stream, encoding, GT), as the set's own image was; each phase's GT is computed
    from its moved scene.

    Parameters
    ----------
    gt : GroundTruth
        The failing image's ground truth (needs ``scene``).
    phases : int, keyword-only
        Number of offsets (:func:`phase_offsets`).
    folder : Path, keyword-only
        Where the images are written (``phase-NN`` + the format's extension).
    output : ImageFormat, keyword-only
        How the set's images are encoded (:meth:`SceneSource.output`); default PNG.
    renderer : SceneRenderer, keyword-only
        Default: this thread's :func:`arenabench.generator.dataset.make.worker_renderer`.
    scene, params : keyword-only
        Another scene of the image (an open parameter's variant) and its drawn parameters;
        default: ``gt``'s own.
    offsets : sequence of (dx, dy), keyword-only
        The offsets instead of :func:`phase_offsets` (``[(0, 0)]``: the scene unmoved).
    """
    from arenabench.fileio import rounded
    from arenabench.generator.dataset.make import ImageFormat, scene_image, worker_renderer
    from arenabench.generator.model.scene import Scene

    if gt.scene is None:
        raise ValueError(f"GT {gt.id!r} holds no scene: cannot re-render it")
    if scene is None:
        scene = Scene.from_dict(gt.to_dict()["scene"])
        params = dict(gt.params or {})
    output = output or ImageFormat()
    renderer = renderer or worker_renderer()
    frame = None
    if gt.frame is not None and gt.frame.size:
        from arenabench.frame import FrameSpec

        frame = FrameSpec(size=int(gt.frame.size[0]), corners=gt.frame.corners or "inner")
    for i, offset in enumerate(phase_offsets(phases) if offsets is None else offsets):
        shift = box_offsets(offset, len(scene.obstacles))
        moved = (scene if not any(offset) else
                 Scene.from_dict(rounded(shifted_scene(scene, shift).to_dict())))
        made = scene_image(moved, sid=gt.id, preset=gt.preset, seed=gt.seed, index=gt.index,
                           params=params or {}, renderer=renderer, output=output,
                           overrides=dict(gt.overrides or {}), frame=frame)
        path = folder / f"phase-{i:02d}.{output.ext}"
        path.write_bytes(made.image_bytes)
        yield PhaseImage(path=path, gt=made.record)


# ------------------------------------------------------------------------------ the check

#: Statuses of a run that did not complete (the program crashed, ran out of time or hit a
#: limit): not a failed run, it says nothing of the answer; the label counts completed runs.
NOT_COMPLETED = ("crash", "timeout", "limit")


def original_output(image: str | Path) -> Any:
    """How the file ``image`` is encoded, read from the file itself (a JPEG's quality and
    chroma subsampling from its tables): what the check uses when the set records no preset.
    """
    from arenabench.fileio import open_regular
    from arenabench.generator.dataset.make import ImageFormat
    from arenabench.imageio import JPEG_SUBSAMPLINGS, ImageLoadError, jpeg_settings

    if Path(image).suffix.lower() not in (".jpg", ".jpeg"):
        return ImageFormat()
    try:
        with open_regular(image) as fh:
            head = fh.read(1 << 20)  # the tables come before the scan
        found = jpeg_settings(head)
    except (OSError, ImageLoadError):
        return ImageFormat("jpeg")
    return ImageFormat("jpeg", jpeg_quality=found.quality or 95,
                       jpeg_subsampling=(found.subsampling if found.subsampling
                                         in JPEG_SUBSAMPLINGS else "420"))


def checked(result: ImageResult) -> bool:
    """Whether the phase check re-runs this image: a failure of a category in
    :data:`CHECKED_CATEGORIES`."""
    return not result.passed and result.category in CHECKED_CATEGORIES


def unchecked_text() -> str:
    """The failure categories the check leaves alone, as reports name them
    (``"markers_not_found, crash, timeout, limit, bad_output"``)."""
    return ", ".join(c for c in CATEGORIES if c not in CHECKED_CATEGORIES)


@dataclass
class _Tally:
    runs: int = 0
    completed: int = 0
    passes: int = 0
    first_error: str = ""

    def add(self, prediction: Prediction | None, passed: bool, error: str = "") -> None:
        self.runs += 1
        if prediction is None or prediction.status in NOT_COMPLETED:
            message = error or (prediction.message if prediction is not None else "")
            line = ((message or "").strip().splitlines() or [""])[0]
            status = prediction.status if prediction is not None else "harness error"
            self.first_error = self.first_error or f"{status}: {line}"[:300]
            return
        self.completed += 1
        self.passes += passed


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
    source: SceneSource | None = None,
    on_image: Callable[[], None] | None = None,
    stop: Callable[[], None] | None = None,
) -> list[ImageResult]:
    """``results`` with :class:`PhaseResult` added to each failing image (``phase``).

    A failing image is re-run at ``phases`` sub-pixel phases of its scene; when none of those
    runs passes, again at the same phases under each other value the preset's open
    parameters allow (:func:`open_variants`), one parameter at a time. A run that does not
    complete (:data:`NOT_COMPLETED`, a harness error, a scene that cannot be re-rendered) is
    counted as tried, not as failed.

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
        Phases per failing image (and per open variant); 0 returns ``results`` unchanged.
    tolerance, area_reference : keyword-only
        The run's scoring settings.
    workers : int, keyword-only
        Pipeline runs in parallel (renders happen in the calling thread, one after another).
    renderer : SceneRenderer, keyword-only
        Default: this thread's reused renderer.
    source : SceneSource, keyword-only
        The set's preset and ``--set`` values: the images' encoding and the open parameters
        to vary. ``None``: each image encoded as its file is, no open parameter varied.
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
    job = _Job(pool=pool, run=run, phases=phases, tolerance=tolerance,
               area_reference=area_reference, renderer=renderer, source=source)
    try:
        try:
            for i in failing:
                checkpoint()  # a stop signal a library swallowed
                folder = Path(tmp, f"{i:06d}")
                folder.mkdir()
                out[i] = replace(results[i], phase=job.check(results[i], gts[i], folder))
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


@dataclass
class _Job:
    """The check of one run's failing images (its pool, pipeline and settings)."""

    pool: ThreadPoolExecutor
    run: Callable[[Path], Prediction]
    phases: int
    tolerance: float
    area_reference: str
    renderer: Any
    source: SceneSource | None

    def check(self, result: ImageResult, gt: GroundTruth, folder: Path) -> PhaseResult:
        output = (self.source.output() if self.source is not None
                  else original_output(result.image))
        own = _Tally()
        self._runs(own, result, gt, folder / "own", output=output)
        variants: list[tuple[Variant, _Tally]] = []
        if own.passes == 0 and self.source is not None and self.source.open:
            todo = open_variants(self.source)
            if todo and not self.source.reproduces(gt):
                _warn(f"phase check of {result.id}: its scene is not drawn again from the "
                      "set's preset: open parameters are not varied")
                todo = []
            for k, variant in enumerate(todo):
                tally = _Tally()
                try:
                    sampled = self.source.sample(gt, variant.settings())
                except Exception as exc:
                    for _ in range(self.phases):
                        tally.add(None, False, f"{type(exc).__name__}: {exc}")
                else:
                    self._runs(tally, result, gt, folder / f"open-{k:02d}", output=output,
                               scene=sampled.scene, params=sampled.params)
                variants.append((variant, tally))
        return PhaseResult(
            phases=self.phases, runs=own.runs, completed=own.completed, passes=own.passes,
            variants=tuple(VariantResult(v.param, v.value, t.runs, t.completed, t.passes,
                                         also=v.also)
                           for v, t in variants),
            first_error=own.first_error or next((t.first_error for _, t in variants
                                                 if t.first_error), ""))

    def _runs(self, tally: _Tally, result: ImageResult, gt: GroundTruth, folder: Path, *,
              output: Any, scene: Any = None, params: dict[str, Any] | None = None) -> None:
        """Render the phases of one scene, run the pipeline on each, add them to ``tally``."""
        from arenabench.eval.datasets.reader import DatasetItem

        folder.mkdir()
        pending = []
        error = ""
        try:
            for image in render_phases(gt, phases=self.phases, folder=folder, output=output,
                                       renderer=self.renderer, scene=scene, params=params):
                pending.append((image, self.pool.submit(_safe_run, self.run, image.path)))
        except Exception as exc:
            error = f"{type(exc).__name__}: {exc}"
            _warn(f"phase check of {result.id}: cannot re-render it: {error}")
        for image, fut in pending:
            prediction, harness = result_of(fut)
            if prediction is None:
                tally.add(None, False, harness)
                continue
            item = DatasetItem(id=result.id, image_path=image.path, gt_path=image.path,
                               gt=image.gt)
            scored = score_sample(item, prediction, tolerance=self.tolerance,
                                  area_reference=self.area_reference)
            tally.add(prediction, scored.passed)
        for _ in range(self.phases - len(pending)):  # phases never rendered
            tally.add(None, False, error)


def _warn(message: str) -> None:
    import sys

    print(f"arenabench: warning: {message}", file=sys.stderr)


def _safe_run(run: Callable[[Path], Prediction], path: Path
              ) -> tuple[Prediction | None, str]:
    """The run's prediction, or ``(None, message)`` for the harness's own failure (a run that
    did not complete, not a failed one)."""
    try:
        return run(path), ""
    except HarnessError as exc:
        return None, f"HarnessError: {exc}"
    except Exception as exc:  # the harness never dies from a bad pipeline
        return Prediction(status="crash", message=f"{type(exc).__name__}: {exc}"), ""


