"""Typed records of an evaluation: what a pipeline predicted, per-image results, summary, report.

Every record converts to and from the JSON of ``report.json`` (schema ``arenabench.report/1``,
keys as in docs/formats.md; extra keys are only ever added, never renamed).
"""

from __future__ import annotations

import base64
from dataclasses import dataclass, field, fields
from typing import Any

from arenabench.competition import DEFAULT_TOLERANCE
from arenabench.gtrecord import DEFAULT_AREA_REFERENCE
from arenabench.records import from_plain, to_plain

REPORT_SCHEMA = "arenabench.report/1"

#: Statuses of a pipeline that answered: ``ok``, or a failure it reported itself.
PIPELINE_STATUSES: tuple[str, ...] = ("ok", "markers_not_found")
#: Statuses the harness assigns when the pipeline did not produce a usable answer
#: (``limit``: an external command failed after hitting a run limit other than the timeout,
#: i.e. memory, processes or file size; the message says which).
HARNESS_STATUSES: tuple[str, ...] = ("crash", "timeout", "limit", "bad_output")
#: Pipeline statuses.
STATUSES: tuple[str, ...] = (*PIPELINE_STATUSES, *HARNESS_STATUSES)
#: Failures of an answer that scoring finds (the status was ``ok``).
SCORING_FAILURES: tuple[str, ...] = ("wrong_count", "area_off")

#: Failure categories, in the order reports list them: the pipeline's own failure statuses,
#: the scoring failures, then the harness's statuses.
CATEGORIES: tuple[str, ...] = (
    *(s for s in PIPELINE_STATUSES if s != "ok"), *SCORING_FAILURES, *HARNESS_STATUSES,
)

#: Pixel spaces a pipeline's obstacle polygons may be given in.
OBSTACLE_SPACES: tuple[str, ...] = ("frame", "image")

class HarnessError(RuntimeError):
    """The harness itself could not run an image (no space for the run's folder, the image
    cannot be copied, the run cannot be prepared): never scored as the pipeline's failure.
    :func:`arenabench.eval.evaluation.evaluate` and ``grade`` stop with it (one line)."""


#: Longest stdout/stderr tail kept per image (characters).
TAIL_CHARS = 2000


def tail(text: str | None, limit: int = TAIL_CHARS) -> str:
    """Last ``limit`` characters of ``text`` (empty for ``None``), prefixed with an ellipsis
    when cut."""
    if not text:
        return ""
    return text if len(text) <= limit else "..." + text[-limit:]


@dataclass(frozen=True)
class Truth:
    """The ground truth one image is scored against.

    Parameters
    ----------
    count : int
        Number of obstacles in the frame.
    area : float
        Reference area in frame px (``visible_px``, ``footprint_px`` or ``contour_px``).
    marker_ids : tuple of int
        Ids of the markers fully in view.
    """

    count: int
    area: float
    marker_ids: tuple[int, ...] = ()


@dataclass(frozen=True)
class Prediction:
    """What a pipeline reported for one image (or why it reported nothing usable).

    Parameters
    ----------
    status : str
        One of :data:`STATUSES`.
    count, area : int or None, float or None
        Reported obstacle count and total area (frame px); ``None`` when not reported.
    marker_ids : tuple of int or None
        Reported marker ids; ``None`` when the pipeline does not report ids.
    message : str
        Why the pipeline failed (empty when it did not).
    stdout, stderr : str
        Tails of the pipeline's output streams (external commands; tracebacks in-process).
    latency_ms : float
        Wall time of the pipeline call in milliseconds (what reports write is
        :attr:`measured_latency_ms`).
    obstacles : tuple of polygons or None
        What the pipeline found, for drawing: one polygon (tuple of (x, y)) per obstacle, in
        ``obstacles_space`` px, simplified to within about 2 px; ``None`` when not reported.
    obstacles_space : {"frame", "image"}
        Whether ``obstacles`` are in rectified frame px or input image px.
    homography : 3 x 3 tuple or None
        The pipeline's input image px -> frame px homography, when it reports one.
    run_images : tuple of RunImage
        Thumbnails of the images an external run left in its working directory (its warp...;
        :mod:`arenabench.eval.runs.run_images`), for the HTML report's failure card; never written
        into ``report.json``, and dropped from an image that passed.
    starved : bool
        A ``timeout`` of a run that spent much of its time waiting for a CPU (the machine was
        busy, :data:`arenabench.eval.runs.predictions.STARVED_SHARE`): what it says of the pipeline
        is nothing.
    """

    status: str
    count: int | None = None
    area: float | None = None
    marker_ids: tuple[int, ...] | None = None
    message: str = ""
    stdout: str = ""
    stderr: str = ""
    latency_ms: float = 0.0
    obstacles: tuple[tuple[tuple[float, float], ...], ...] | None = None
    obstacles_space: str = "frame"
    homography: tuple[tuple[float, float, float], ...] | None = None
    run_images: tuple[RunImage, ...] = field(default=(), repr=False)
    starved: bool = False

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {self.status!r}")
        if self.obstacles_space not in OBSTACLE_SPACES:
            raise ValueError(
                f"obstacles_space must be one of {OBSTACLE_SPACES}, got {self.obstacles_space!r}"
            )

    def to_json(self) -> dict[str, Any]:
        """Every field, exactly, as JSON (``run_images`` as :meth:`RunImage.to_json`): what a
        grade's ``partial-results.jsonl`` keeps to score the same prediction again."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["run_images"] = [image.to_json() for image in self.run_images]
        return d

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Prediction:
        """Inverse of :meth:`to_json` (keys it does not know are ignored).

        Raises
        ------
        TypeError, ValueError, KeyError
            When ``d`` is not a prediction.
        """
        names = {f.name for f in fields(cls)}
        kept = {k: _tuples(v) for k, v in d.items() if k in names and k != "run_images"}
        images = tuple(RunImage.from_json(i) for i in d.get("run_images") or ())
        return cls(**kept, run_images=images)

    @property
    def measured_latency_ms(self) -> float | None:
        """The latency reports write and latency statistics use: ``None`` for a timed-out
        image (its run was cut short, not timed) and for one whose pipeline never ran
        (latency 0), else :attr:`latency_ms`."""
        if self.status == "timeout" or not self.latency_ms > 0:
            return None
        return self.latency_ms

    def drawing_dict(self) -> dict[str, Any]:
        """The drawing fields as JSON (empty when the pipeline reported no polygons)."""
        out: dict[str, Any] = {}
        if self.obstacles is not None:
            out["obstacles"] = [[[x, y] for x, y in poly] for poly in self.obstacles]
            out["obstacles_space"] = self.obstacles_space
        if self.homography is not None:
            out["homography"] = [list(row) for row in self.homography]
        return out


def drawing_from_json(pred: dict[str, Any]) -> dict[str, Any]:
    """``Prediction`` keyword arguments from the drawing fields of a ``pred`` record."""
    out: dict[str, Any] = {}
    if pred.get("obstacles") is not None:
        out["obstacles"] = tuple(
            tuple((float(x), float(y)) for x, y in poly) for poly in pred["obstacles"]
        )
        out["obstacles_space"] = str(pred.get("obstacles_space", "frame"))
    if pred.get("homography") is not None:
        out["homography"] = tuple(tuple(float(v) for v in row) for row in pred["homography"])
    return out


@dataclass(frozen=True)
class ImageScore:
    """Metrics of one image (output of :func:`arenabench.eval.scoring.metrics.score_image`).

    ``area_err_kind`` is ``"relative"`` normally and ``"absolute_px"`` when the ground-truth
    area is 0 (``area_rel_err`` then holds the absolute error in px; docs/ground-truth.md).
    """

    passed: bool
    category: str | None
    count_err: int | None
    area_rel_err: float | None
    area_err_kind: str
    marker_ids_ok: bool | None


def _tuples(value: Any) -> Any:
    """JSON lists back to the tuples of a record's fields (nested)."""
    return tuple(_tuples(v) for v in value) if isinstance(value, list) else value


def _phase_from_json(d: dict[str, Any] | None) -> PhaseResult | None:
    return PhaseResult.from_dict(d) if d else None


@dataclass(frozen=True)
class ImageResult:
    """Everything the report says about one image."""

    id: str
    image: str
    truth: Truth
    prediction: Prediction
    score: ImageScore
    gt_area_visible: float = 0.0
    gt_area_footprint: float = 0.0
    params: dict[str, float] = field(default_factory=dict)
    #: The phase check's finding on a failing image (``PhaseResult``), ``None`` when not run.
    phase: PhaseResult | None = None

    @property
    def passed(self) -> bool:
        """Whether the image passed."""
        return self.score.passed

    @property
    def category(self) -> str | None:
        """Failure category, ``None`` when the image passed."""
        return self.score.category

    def to_dict(self) -> dict[str, Any]:
        """JSON form (the ``images[]`` entries of ``report.json``)."""
        p, s = self.prediction, self.score
        return {
            "id": self.id,
            "image": self.image,
            "pass": s.passed,
            "category": s.category,
            "status": p.status,
            "message": p.message,
            "gt": {
                "count": self.truth.count,
                "area": self.truth.area,
                "marker_ids": list(self.truth.marker_ids),
                "area_visible_px": self.gt_area_visible,
                "area_footprint_px": self.gt_area_footprint,
            },
            "pred": {
                "count": p.count,
                "area": p.area,
                "marker_ids": None if p.marker_ids is None else list(p.marker_ids),
                **p.drawing_dict(),
            },
            "area_rel_err": s.area_rel_err,
            "area_err_kind": s.area_err_kind,
            "count_err": s.count_err,
            "marker_ids_ok": s.marker_ids_ok,
            "latency_ms": p.measured_latency_ms,
            "stdout_tail": p.stdout,
            "stderr_tail": p.stderr,
            "params": dict(self.params),
            **({} if self.phase is None else {"phase": self.phase.to_dict()}),
            **({"starved": True} if p.starved else {}),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ImageResult:
        """Inverse of :meth:`to_dict` (tolerates a minimal entry: id, pass, gt, pred)."""
        gt, pred = d.get("gt", {}), d.get("pred", {})
        ids = pred.get("marker_ids")
        prediction = Prediction(
            status=d.get("status", "ok"),
            count=pred.get("count"),
            area=pred.get("area"),
            marker_ids=None if ids is None else tuple(int(i) for i in ids),
            message=d.get("message", ""),
            stdout=d.get("stdout_tail", ""),
            stderr=d.get("stderr_tail", ""),
            latency_ms=float(d.get("latency_ms") or 0.0),
            starved=bool(d.get("starved", False)),
            **drawing_from_json(pred),
        )
        truth = Truth(
            count=int(gt.get("count", 0)),
            area=float(gt.get("area", 0.0)),
            marker_ids=tuple(int(i) for i in gt.get("marker_ids", [])),
        )
        score = ImageScore(
            passed=bool(d.get("pass")),
            category=d.get("category"),
            count_err=d.get("count_err"),
            area_rel_err=d.get("area_rel_err"),
            area_err_kind=d.get("area_err_kind", "relative"),
            marker_ids_ok=d.get("marker_ids_ok"),
        )
        return cls(
            id=str(d["id"]),
            image=d.get("image", ""),
            truth=truth,
            prediction=prediction,
            score=score,
            gt_area_visible=float(gt.get("area_visible_px", truth.area)),
            gt_area_footprint=float(gt.get("area_footprint_px", truth.area)),
            params={k: float(v) for k, v in d.get("params", {}).items()},
            phase=_phase_from_json(d.get("phase")),
        )


@dataclass(frozen=True)
class Summary:
    """Summary metrics of a run (the ``summary`` object of ``report.json``).

    ``area_rel_err`` holds statistics of ``|area_rel_err|``; ``area_rel_err_signed`` of the
    signed value. Both use only images where the pipeline answered (status ``ok``) and the
    ground-truth area is non-zero. ``count_mae`` uses images with a reported count.
    ``marker_id_accuracy`` is ``None`` when the pipeline never reports ids.
    """

    n: int
    n_passed: int
    pass_rate: float
    pass_rate_ci95: tuple[float, float]
    count_exact_rate: float
    count_mae: float | None
    area_rel_err: dict[str, Any]
    area_rel_err_signed: dict[str, Any]
    marker_id_accuracy: float | None
    failures: dict[str, int]
    latency_ms: dict[str, Any]
    #: Phase check (docs/phase-check.md): robust and phase-dependent failures as fractions of
    #: all images, and its counts; ``None`` when no image was phase-checked.
    robust_failure_rate: float | None = None
    phase_dependent_failure_rate: float | None = None
    phase_check: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON form: the fields, in order."""
        return to_plain(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Summary:
        """Inverse of :meth:`to_dict` (a summary written before ``n_passed`` was kept: from
        the pass rate; a missing interval: [0, 1])."""
        return from_plain(cls, {"pass_rate_ci95": (0.0, 1.0), "count_exact_rate": 0.0,
                                "count_mae": None, "area_rel_err": {},
                                "area_rel_err_signed": {}, "marker_id_accuracy": None,
                                "failures": {}, "latency_ms": {}, **d},
                          **({} if "n_passed" in d else
                             {"n_passed": round(d["pass_rate"] * d["n"])}))


@dataclass(frozen=True)
class Report:
    """A whole evaluation: settings, summary, per-image results and the parameter breakdown.

    ``complete`` is ``False`` for a run stopped early (SIGINT/SIGTERM); its summary then
    covers the ``n_done`` images evaluated before the stop, of ``n_total`` (when known).
    """

    pipeline: str
    dataset: str
    area_reference: str
    tolerance: float
    summary: Summary
    images: tuple[ImageResult, ...]
    breakdown: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    schema: str = REPORT_SCHEMA
    #: Scene parameters and derived facts ranked by how well they separate failures from
    #: passes (:func:`arenabench.eval.scoring.breakdown.rank_causes`), strongest first.
    causes: tuple[dict[str, Any], ...] = ()
    complete: bool = True
    n_done: int | None = None
    n_total: int | None = None
    #: The interpreter that ran a command's script, where it was probed (``arenabench check``):
    #: ``executable``, ``source``, ``python``, ``numpy``, ``cv2``
    #: (:meth:`arenabench.eval.runs.competition_env.Interpreter.to_dict`).
    interpreter: dict[str, Any] | None = None
    #: SHA-256 of the dataset's ``manifest.jsonl`` (which set was scored: ``--compare``
    #: refuses reports of different sets); ``None`` for a dataset without one.
    manifest_sha256: str | None = None
    #: Systematic errors of the answers
    #: (:func:`arenabench.eval.scoring.breakdown.systematic_errors`): the same count offset or
    #: area factor on most answered images.
    systematic: tuple[dict[str, Any], ...] = ()

    @property
    def images_done(self) -> int:
        """Images evaluated (``n_done``, or every image of a complete report)."""
        return len(self.images) if self.n_done is None else self.n_done

    def to_dict(self) -> dict[str, Any]:
        """JSON form (``report.json``)."""
        return {
            "schema": self.schema,
            "pipeline": self.pipeline,
            "dataset": self.dataset,
            "manifest_sha256": self.manifest_sha256,
            "area_reference": self.area_reference,
            "tolerance": self.tolerance,
            "complete": self.complete,
            "n_done": self.images_done,
            **({} if self.n_total is None else {"n_total": self.n_total}),
            **({} if self.interpreter is None else {"interpreter": dict(self.interpreter)}),
            "summary": self.summary.to_dict(),
            "breakdown": self.breakdown,
            "causes": [dict(c) for c in self.causes],
            "systematic": [dict(c) for c in self.systematic],
            "images": [r.to_dict() for r in self.images],
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Report:
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        ValueError
            When ``schema`` is not ``arenabench.report/1``.
        """
        if d.get("schema") != REPORT_SCHEMA:
            raise ValueError(f"report schema must be {REPORT_SCHEMA!r}, got {d.get('schema')!r}")
        return cls(
            pipeline=str(d.get("pipeline", "")),
            dataset=str(d.get("dataset", "")),
            area_reference=str(d.get("area_reference", DEFAULT_AREA_REFERENCE)),
            tolerance=float(d.get("tolerance", DEFAULT_TOLERANCE)),
            summary=Summary.from_dict(d["summary"]),
            images=tuple(ImageResult.from_dict(i) for i in d.get("images", [])),
            breakdown=dict(d.get("breakdown", {})),
            causes=tuple(dict(c) for c in d.get("causes", [])),
            systematic=tuple(dict(c) for c in d.get("systematic") or []),
            manifest_sha256=(None if d.get("manifest_sha256") is None
                             else str(d["manifest_sha256"])),
            complete=bool(d.get("complete", True)),
            n_done=None if d.get("n_done") is None else int(d["n_done"]),
            n_total=None if d.get("n_total") is None else int(d["n_total"]),
            interpreter=(dict(d["interpreter"]) if isinstance(d.get("interpreter"), dict)
                         else None),
        )


#: The phase check's labels of a failing image (docs/phase-check.md), in the order reports
#: list them: ``robust`` (fails under every phase and open-parameter variant that completed),
#: ``phase_dependent`` (passes at some sub-pixel phase), ``depends_on_open`` (fails at every
#: phase but passes when an open parameter of the preset takes another allowed value: the
#: verdict rests on what the evidence does not pin), ``unchecked`` (no run completed).
PHASE_LABELS: tuple[str, ...] = ("robust", "phase_dependent", "depends_on_open", "unchecked")


def _counts(runs: int, completed: int, passes: int, what: str) -> None:
    if not 0 <= passes <= completed <= runs:
        raise ValueError(f"{what}: need 0 <= passes <= completed <= runs, got passes={passes}, "
                         f"completed={completed}, runs={runs}")


@dataclass(frozen=True)
class VariantResult:
    """The runs of a failing image with one open parameter at another value.

    Attributes
    ----------
    param : str
        The open parameter (``lighting.east_fill``).
    value : Any
        The value it was given.
    runs, completed, passes : int
        Runs tried (one per phase), completed (not a crash, timeout or limit) and passed.
    also : tuple of (str, value)
        The parameters that moved with it (the preset's ``moves_with``) and their values.
    """

    param: str
    value: Any
    runs: int
    completed: int
    passes: int
    also: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        _counts(self.runs, self.completed, self.passes, f"variant {self.param}")

    def to_dict(self) -> dict[str, Any]:
        """JSON form (an entry of a phase record's ``open``)."""
        out = {"param": self.param, "value": self.value, "runs": self.runs,
               "completed": self.completed, "passes": self.passes}
        if self.also:
            out["with"] = dict(self.also)
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> VariantResult:
        """Inverse of :meth:`to_dict`."""
        return cls(param=str(d["param"]), value=d["value"], runs=int(d["runs"]),
                   completed=int(d["completed"]), passes=int(d["passes"]),
                   also=tuple(sorted(dict(d.get("with", {})).items())))


@dataclass(frozen=True)
class PhaseResult:
    """What the phase check found for one failing image.

    Parameters
    ----------
    phases : int
        Sub-pixel phases per scene (``N``).
    runs, completed, passes : int
        Runs of the image's own scene: tried (``N``), completed (a run that crashed, timed
        out, hit a limit or met a harness error did not complete: it is not a failed run) and
        passed.
    variants : tuple of VariantResult
        The runs under each other value of the preset's open parameters (tried only when no
        run of the own scene passed).
    first_error : str
        The first line of the first run that did not complete (``""``: all completed).
    """

    phases: int
    runs: int
    completed: int
    passes: int
    variants: tuple[VariantResult, ...] = ()
    first_error: str = ""

    def __post_init__(self) -> None:
        if self.phases < 1:
            raise ValueError(f"phases must be >= 1, got {self.phases}")
        _counts(self.runs, self.completed, self.passes, "phase check")

    @property
    def n(self) -> int:
        """Phases per scene (``N``)."""
        return self.phases

    @property
    def total_runs(self) -> int:
        """Runs tried, open variants included."""
        return self.runs + sum(v.runs for v in self.variants)

    @property
    def total_completed(self) -> int:
        """Runs that completed, open variants included."""
        return self.completed + sum(v.completed for v in self.variants)

    @property
    def total_passes(self) -> int:
        """Runs that passed, open variants included."""
        return self.passes + sum(v.passes for v in self.variants)

    @property
    def depends_on(self) -> tuple[str, ...]:
        """The open parameters under whose other values some run passed."""
        return tuple(dict.fromkeys(v.param for v in self.variants if v.passes))

    @property
    def label(self) -> str:
        """One of :data:`PHASE_LABELS`, over completed runs only."""
        if self.total_completed == 0:
            return "unchecked"
        if self.passes:
            return "phase_dependent"
        if self.depends_on:
            return "depends_on_open"
        return "robust"

    def text(self) -> str:
        """What reports print: ``3/8 phase-dependent``, ``0/24 robust``, ``0/8 depends on
        open lighting.east_fill``, ``0/0 unchecked (8 runs did not complete)``."""
        label = self.label
        words = ("depends on open " + ", ".join(self.depends_on)
                 if label == "depends_on_open" else label.replace("_", "-"))
        passes = self.passes if label == "phase_dependent" else self.total_passes
        done = self.completed if label == "phase_dependent" else self.total_completed
        missing = self.total_runs - self.total_completed
        return f"{passes}/{done} {words}" + (
            f" ({missing} of {self.total_runs} runs did not complete)" if missing else "")

    def to_dict(self) -> dict[str, Any]:
        """JSON form (the ``phase`` object of a ``report.json`` image): ``runs``,
        ``completed``, ``passes`` (every run, open variants included), ``class``, ``phases``,
        and when there are some ``open`` (the variants), ``depends_on`` and ``first_error``.
        """
        out: dict[str, Any] = {"runs": self.total_runs, "completed": self.total_completed,
                               "passes": self.total_passes, "class": self.label,
                               "phases": self.phases}
        if self.variants:
            out["open"] = [v.to_dict() for v in self.variants]
        if self.depends_on:
            out["depends_on"] = list(self.depends_on)
        if self.first_error:
            out["first_error"] = self.first_error
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PhaseResult:
        """Inverse of :meth:`to_dict` (a record of ``passes`` and ``n`` only, as earlier
        reports wrote, reads as ``n`` completed runs)."""
        if "runs" not in d:
            n = int(d["n"])
            return cls(phases=n, runs=n, completed=n, passes=int(d["passes"]))
        variants = tuple(VariantResult.from_dict(v) for v in d.get("open") or [])
        return cls(phases=int(d["phases"]),
                   runs=int(d["runs"]) - sum(v.runs for v in variants),
                   completed=int(d["completed"]) - sum(v.completed for v in variants),
                   passes=int(d["passes"]) - sum(v.passes for v in variants),
                   variants=variants, first_error=str(d.get("first_error", "")))


@dataclass(frozen=True)
class RunImage:
    """A thumbnail of one image a run left in its working directory.

    Attributes
    ----------
    name : str
        Its file name (printable, at most
        :data:`~arenabench.eval.runs.run_images.MAX_NAME_CHARS` characters).
    jpeg : bytes
        The thumbnail, JPEG-encoded, at most :data:`~arenabench.limits.RUN_IMAGE_THUMB_PX` px
        on its longer side.
    width, height : int
        The size of the image the run wrote, px.
    """

    name: str
    jpeg: bytes
    width: int
    height: int

    def data_uri(self) -> str:
        """The thumbnail as a ``data:image/jpeg;base64,...`` URI (for a self-contained page)."""
        return "data:image/jpeg;base64," + base64.b64encode(self.jpeg).decode("ascii")

    def to_json(self) -> dict[str, Any]:
        """JSON form (a big run's temporary result file keeps thumbnails this way)."""
        return {"name": self.name, "jpeg": base64.b64encode(self.jpeg).decode("ascii"),
                "width": self.width, "height": self.height}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> RunImage:
        """Inverse of :meth:`to_json`."""
        return cls(name=str(d["name"]), jpeg=base64.b64decode(d["jpeg"]),
                   width=int(d["width"]), height=int(d["height"]))
