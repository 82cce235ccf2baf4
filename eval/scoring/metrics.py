"""Pure metric functions: score one image, summarise many, Wilson interval. No I/O, no printing.

Failure category of a failing image (exactly one, first match wins):

1. the pipeline gave no usable answer: its status (``crash``, ``timeout``, ``limit``,
   ``bad_output``, ``markers_not_found``); these are mutually exclusive, so no count or area
   is judged;
2. ``wrong_count``: predicted count differs from the ground truth;
3. ``area_off``: the count is right but ``|area_rel_err| > tolerance``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

# DEFAULT_TOLERANCE is declared with the competition rules; imported from here too
from arenabench.competition import DEFAULT_TOLERANCE as DEFAULT_TOLERANCE
from arenabench.competition import OutputFormatError, check_area, check_count

from .gt_facts import gt_facts
from .results import CATEGORIES, ImageResult, ImageScore, Prediction, Summary, Truth

if TYPE_CHECKING:
    from arenabench.eval.datasets.reader import DatasetItem

#: A GT area below this (px², a millionth of a pixel) is 0 in effect: its error is absolute.
ZERO_AREA_PX = 1e-6


def wilson_interval(successes: int, n: int, *, z: float = 1.959963984540054) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion.

    Parameters
    ----------
    successes : int
        Number of successes (0 <= successes <= n).
    n : int
        Number of trials; ``n == 0`` gives ``(0.0, 1.0)``.
    z : float
        Normal quantile (default: 95 % two-sided).

    Returns
    -------
    (float, float)
        Lower and upper bound, clipped to [0, 1].
    """
    if n < 0 or successes < 0 or successes > n:
        raise ValueError(f"need 0 <= successes <= n, got successes={successes!r}, n={n!r}")
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    z2 = z * z
    denom = 1.0 + z2 / n
    centre = (p + z2 / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / denom
    # the exact ends where the data reach them (rounding left 5.6e-17 for 0 of 3)
    lo = 0.0 if successes == 0 else max(0.0, centre - half)
    hi = 1.0 if successes == n else min(1.0, centre + half)
    return lo, hi


def area_error(pred_area: float, gt_area: float) -> tuple[float, str]:
    """Area error of a prediction.

    Returns
    -------
    (float, str)
        ``((pred - gt) / gt, "relative")``, or ``(pred - gt, "absolute_px")`` when
        ``gt_area`` is below :data:`ZERO_AREA_PX` (0, or ``1e-320``, whose relative error
        would overflow and blame the pipeline).
    """
    if abs(float(gt_area)) < ZERO_AREA_PX:
        return float(pred_area) - float(gt_area), "absolute_px"
    return (float(pred_area) - float(gt_area)) / float(gt_area), "relative"


def _valid(check, value: object) -> bool:
    """Whether ``value`` passes one of the competition's answer checks (one rule, stated in
    :mod:`arenabench.competition`)."""
    try:
        check(value)
    except OutputFormatError:
        return False
    return True


def score_image(
    truth: Truth, prediction: Prediction, *, tolerance: float = DEFAULT_TOLERANCE
) -> ImageScore:
    """Score one prediction against its ground truth.

    Parameters
    ----------
    truth : Truth
        Ground-truth count, area (px) and ids of markers in view.
    prediction : Prediction
        What the pipeline reported.
    tolerance : float
        Largest passing ``|area_rel_err|`` (absolute px when the GT area is 0).

    Returns
    -------
    ImageScore
        Pass flag, failure category, count error, area error and marker-id check.
    """
    if not tolerance >= 0:
        raise ValueError(f"tolerance must be >= 0, got {tolerance!r}")
    # Defence in depth: adapters already refuse these, but a non-finite, negative or fractional
    # value must never pass (abs(nan) > tolerance is False).
    count_ok = _valid(check_count, prediction.count)
    area_ok = _valid(check_area, prediction.area)
    count_err = int(prediction.count) - int(truth.count) if count_ok else None
    rel, kind = (None, "relative")
    if prediction.status == "ok" and area_ok:
        rel, kind = area_error(prediction.area, truth.area)
        if not math.isfinite(rel):
            rel = None
    if prediction.status == "ok" and prediction.marker_ids is None:
        ids_ok = None
    else:
        ids_ok = set(prediction.marker_ids or ()) == set(truth.marker_ids)
    if prediction.status != "ok":
        category: str | None = prediction.status
    elif count_err is None or rel is None:
        category = "bad_output"
    elif count_err != 0:
        category = "wrong_count"
    elif abs(rel) > tolerance:
        category = "area_off"
    else:
        category = None
    return ImageScore(
        passed=category is None,
        category=category,
        count_err=count_err,
        area_rel_err=rel,
        area_err_kind=kind,
        marker_ids_ok=ids_ok,
    )


def _stats(values: Sequence[float], keys: Sequence[str]) -> dict[str, float | None]:
    arr = np.asarray(values, dtype=np.float64)
    out: dict[str, float | None] = {}
    for key in keys:
        if arr.size == 0:
            out[key] = None
        elif key == "median":
            out[key] = float(np.median(arr))
        elif key == "mean":
            out[key] = float(np.mean(arr))
        elif key == "max":
            out[key] = float(np.max(arr))
        elif key == "min":
            out[key] = float(np.min(arr))
        elif key.startswith("p"):
            out[key] = float(np.percentile(arr, float(key[1:])))
        else:  # pragma: no cover - programming error
            raise ValueError(f"unknown statistic {key!r}")
    return out


def summarize(
    scores: Sequence[ImageScore],
    predictions: Sequence[Prediction],
) -> Summary:
    """Summary metrics over images.

    Parameters
    ----------
    scores : sequence of ImageScore
        Per-image scores.
    predictions : sequence of Prediction
        The matching predictions (same order; used for latency).

    Returns
    -------
    Summary
        Pass rate with 95 % Wilson interval, count exact rate and MAE, area error statistics
        (absolute and signed; relative-kind errors only), marker-id accuracy, failures by
        category, latency median / p95.
    """
    if len(scores) != len(predictions):
        raise ValueError(
            f"scores and predictions must have the same length, got {len(scores)} "
            f"and {len(predictions)}"
        )
    n = len(scores)
    passed = sum(1 for s in scores if s.passed)
    count_errs = [abs(s.count_err) for s in scores if s.count_err is not None]
    exact = sum(
        1 for s, p in zip(scores, predictions, strict=True) if p.status == "ok" and s.count_err == 0
    )
    rels = [
        s.area_rel_err
        for s in scores
        if s.area_rel_err is not None and s.area_err_kind == "relative"
    ]
    ids = [s.marker_ids_ok for s in scores if s.marker_ids_ok is not None]
    failures = {c: 0 for c in CATEGORIES}
    for s in scores:
        if s.category is not None:
            failures[s.category] += 1
    return Summary(
        n=n,
        n_passed=passed,
        pass_rate=passed / n if n else 0.0,
        pass_rate_ci95=wilson_interval(passed, n),
        count_exact_rate=exact / n if n else 0.0,
        count_mae=float(np.mean(count_errs)) if count_errs else None,
        area_rel_err=_stats([abs(r) for r in rels], ("median", "p95", "max")),
        area_rel_err_signed=_stats(rels, ("median", "mean", "p5", "p95", "min", "max")),
        marker_id_accuracy=(sum(ids) / len(ids)) if ids else None,
        failures=failures,
        # a timed-out image has no latency (nor one that never ran): undefined, not 0
        latency_ms=_stats([ms for p in predictions if (ms := p.measured_latency_ms) is not None],
                          ("median", "p95")),
    )


def score_sample(
    sample: DatasetItem, pred: Prediction, *, tolerance: float, area_reference: str
) -> ImageResult:
    """Score one prediction against a dataset item's ground truth, as an
    :class:`~arenabench.eval.scoring.results.ImageResult` (its ``params``: the item's, and the facts
    :func:`~arenabench.eval.scoring.gt_facts.gt_facts` reads from its GT)."""
    truth = sample.truth(area_reference=area_reference)
    score = score_image(truth, pred, tolerance=tolerance)
    if score.passed and pred.run_images:  # only a failure card shows them
        pred = replace(pred, run_images=())
    return ImageResult(
        id=sample.id,
        image=str(sample.image_path),
        truth=truth,
        prediction=pred,
        score=score,
        gt_area_visible=float(sample.gt.area.visible_px),
        gt_area_footprint=float(sample.gt.area.footprint_px),
        params={**sample.params, **gt_facts(sample.gt)},
    )
