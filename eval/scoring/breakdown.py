"""Metrics binned by the scene parameters that vary in a dataset (so failures that cluster at
high tilt or low light show at a glance)."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from .results import CATEGORIES, ImageResult

#: Parameters with at most this many distinct values get one bin per value.
MAX_DISCRETE = 6


def bin_edges(values: Sequence[float], *, bins: int = 4) -> list[float]:
    """Quantile bin edges of ``values`` (duplicates removed; at least two edges).

    Parameters
    ----------
    values : sequence of float
        Parameter values.
    bins : int
        Number of quantile bins wanted (fewer when values repeat).
    """
    if bins < 1:
        raise ValueError(f"bins must be >= 1, got {bins!r}")
    arr = np.asarray(values, dtype=np.float64)
    edges = np.unique(np.quantile(arr, np.linspace(0.0, 1.0, bins + 1)))
    if edges.size < 2:
        edges = np.array([arr.min(), arr.max()])
    return [float(e) for e in edges]


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def _bin_stats(results: Sequence[ImageResult]) -> dict[str, Any]:
    n = len(results)
    passed = sum(r.passed for r in results)
    rels = [
        abs(r.score.area_rel_err)
        for r in results
        if r.score.area_rel_err is not None and r.score.area_err_kind == "relative"
    ]
    failures = {c: 0 for c in CATEGORIES}
    for r in results:
        if r.category is not None:
            failures[r.category] += 1
    return {
        "n": n,
        "pass_rate": passed / n if n else None,
        "count_exact_rate": (
            sum(1 for r in results if r.prediction.status == "ok" and r.score.count_err == 0) / n
            if n
            else None
        ),
        "area_rel_err_median": float(np.median(rels)) if rels else None,
        "failures": {c: v for c, v in failures.items() if v},
    }


def breakdown(results: Sequence[ImageResult], *, bins: int = 4) -> dict[str, list[dict[str, Any]]]:
    """Per-parameter binned metrics for the parameters that vary.

    Parameters
    ----------
    results : sequence of ImageResult
        Scored images with their ``params``.
    bins : int
        Quantile bins for continuous parameters.

    Returns
    -------
    dict
        ``{param: [{"bin": label, "lo": lo, "hi": hi, "n", "pass_rate", "count_exact_rate",
        "area_rel_err_median", "failures"}, ...]}``; bins are ``[lo, hi)`` except the last,
        which is closed. Parameters missing from some images are binned over the others.
    """
    keys = sorted({k for r in results for k in r.params})
    out: dict[str, list[dict[str, Any]]] = {}
    for key in keys:
        have = [r for r in results if key in r.params and np.isfinite(r.params[key])]
        values = np.array([r.params[key] for r in have], dtype=np.float64)
        distinct = np.unique(values)
        if distinct.size < 2:
            continue
        rows: list[dict[str, Any]] = []
        if distinct.size <= MAX_DISCRETE:
            for v in distinct:
                members = [r for r, x in zip(have, values, strict=True) if x == v]
                rows.append({"bin": _fmt(v), "lo": float(v), "hi": float(v), **_bin_stats(members)})
        else:
            edges = bin_edges(values, bins=bins)
            for i, (lo, hi) in enumerate(itertools.pairwise(edges)):
                last = i == len(edges) - 2
                mask = (values >= lo) & ((values <= hi) if last else (values < hi))
                members = [r for r, m in zip(have, mask, strict=True) if m]
                label = f"[{_fmt(lo)}, {_fmt(hi)}{']' if last else ')'}"
                rows.append({"bin": label, "lo": lo, "hi": hi, **_bin_stats(members)})
        out[key] = rows
    return out


def spread(rows: Sequence[dict[str, Any]]) -> float:
    """Difference between the best and worst bin pass rate (how much a parameter matters)."""
    rates = [r["pass_rate"] for r in rows if r.get("pass_rate") is not None and r["n"] > 0]
    return (max(rates) - min(rates)) if rates else 0.0


def importance(rows: Sequence[dict[str, Any]]) -> tuple[float, float]:
    """Sort key of a parameter: pass-rate spread across its bins, then the spread of the bins'
    median ``|area_rel_err|`` (larger = the parameter matters more)."""
    errs = [r["area_rel_err_median"] for r in rows if r.get("area_rel_err_median") is not None]
    return spread(rows), (max(errs) - min(errs)) if errs else 0.0


#: Fewest failures and passes a parameter needs before it is ranked as a cause.
MIN_GROUP = 2
#: Largest p value of a cause that reports and ``arenabench check`` call the strongest.
CAUSE_P_VALUE = 0.05


def rank_causes(results: Sequence[ImageResult], *, top: int | None = None) -> list[dict[str, Any]]:
    """Scene parameters (and derived facts) ranked by how well they separate failing images
    from passing ones (docs/ground-truth.md, "Causes").

    The effect size is the area under the ROC curve of the parameter as a failure score,
    ``auc = P(x_fail > x_pass) + P(x_fail = x_pass) / 2`` over all (failing, passing) pairs
    (the Mann-Whitney U statistic divided by ``n_fail * n_pass``), folded to a strength
    ``|2 auc - 1|`` (the rank-biserial correlation's size): 0 = no separation, 1 = every
    failure lies beyond every pass.

    Parameters
    ----------
    results : sequence of ImageResult
        Scored images with their ``params``.
    top : int, optional
        Keep only the ``top`` strongest.

    Returns
    -------
    list of dict
        ``{"param", "strength", "auc", "direction" ("higher": failures have the larger
        values, or "lower"), "p_value" (two-sided, normal approximation of U),
        "n_fail", "n_pass", "fail_median", "pass_median"}``, strongest first; parameters
        that do not vary or have fewer than :data:`MIN_GROUP` failures or passes are left
        out.
    """
    import math

    keys = sorted({k for r in results for k in r.params})
    out: list[dict[str, Any]] = []
    for key in keys:
        have = [r for r in results if key in r.params and np.isfinite(r.params[key])]
        fail = np.array([r.params[key] for r in have if not r.passed], dtype=np.float64)
        good = np.array([r.params[key] for r in have if r.passed], dtype=np.float64)
        if fail.size < MIN_GROUP or good.size < MIN_GROUP:
            continue
        if np.unique(np.concatenate([fail, good])).size < 2:
            continue
        # the pair counts from the sorted passes: n log n, not an n_fail x n_pass matrix
        # (590 MB and minutes at 100,000 images); the same integers
        ordered = np.sort(good)
        below = np.searchsorted(ordered, fail, side="left")
        greater = below.sum()
        ties = (np.searchsorted(ordered, fail, side="right") - below).sum()
        n1, n2 = fail.size, good.size
        u = greater + ties / 2.0
        auc = float(u / (n1 * n2))
        sd = math.sqrt(n1 * n2 * (n1 + n2 + 1) / 12.0)
        z = abs(u - n1 * n2 / 2.0) / sd if sd > 0 else 0.0
        out.append({
            "param": key,
            "strength": abs(2.0 * auc - 1.0),
            "auc": auc,
            "direction": "higher" if auc >= 0.5 else "lower",
            "p_value": math.erfc(z / math.sqrt(2.0)),
            "n_fail": int(n1),
            "n_pass": int(n2),
            "fail_median": float(np.median(fail)),
            "pass_median": float(np.median(good)),
        })
    out.sort(key=lambda c: (-c["strength"], c["p_value"], c["param"]))
    return out[:top] if top is not None else out


#: Fewest answered images showing the same error before it is called systematic, and the
#: share of the answered images they must be.
MIN_SYSTEMATIC, SYSTEMATIC_SHARE = 3, 0.5


def systematic_errors(results: Sequence[ImageResult], *, tolerance: float
                      ) -> list[dict[str, Any]]:
    """Errors the answers make the same way on most images (what no scene fact can separate
    when every image fails alike): a count offset (``answered GT + 4``: the four markers
    counted as obstacles) and an area factor (``area = GT x 1.21``: another frame or area
    definition).

    Over the images the pipeline answered (status ``ok`` with a count): the most common
    non-zero ``count_err`` is systematic when at least :data:`MIN_SYSTEMATIC` images and
    :data:`SYSTEMATIC_SHARE` of them have it; the median ratio answered / GT area (non-zero GT
    area) is systematic when it is off by more than ``tolerance`` and as many images lie
    within ``tolerance`` of it.

    Returns
    -------
    list of dict
        ``{"kind": "count_offset", "offset", "n", "of", "text"}`` and / or ``{"kind":
        "area_factor", "factor", "n", "of", "text"}``; ``text`` is the sentence reports print
        (``answered GT + 4 on 50 of 50 answered images``).
    """
    from collections import Counter

    answered = [r for r in results
                if r.prediction.status == "ok" and r.score.count_err is not None]
    out: list[dict[str, Any]] = []
    offsets = Counter(r.score.count_err for r in answered if r.score.count_err)
    if offsets:
        offset, n = min(offsets.items(), key=lambda kv: (-kv[1], abs(kv[0]), kv[0]))
        if n >= MIN_SYSTEMATIC and n >= SYSTEMATIC_SHARE * len(answered):
            sign = "+" if offset > 0 else "-"
            out.append({"kind": "count_offset", "offset": int(offset), "n": n,
                        "of": len(answered),
                        "text": f"answered GT {sign} {abs(offset)} on {n} of {len(answered)} "
                                "answered images"})
    ratios = np.array([r.prediction.area / r.truth.area for r in answered
                       if r.prediction.area is not None and r.truth.area > 0], dtype=np.float64)
    ratios = ratios[np.isfinite(ratios)]
    if ratios.size >= MIN_SYSTEMATIC:
        factor = float(np.median(ratios))
        n = int(np.sum(np.abs(ratios - factor) <= tolerance * factor))
        if (abs(factor - 1.0) > tolerance and n >= MIN_SYSTEMATIC
                and n >= SYSTEMATIC_SHARE * ratios.size):
            out.append({"kind": "area_factor", "factor": factor, "n": n, "of": int(ratios.size),
                        "text": f"answered an area of GT x {factor:.3g} on {n} of "
                                f"{ratios.size} answered images"})
    return out


def systematic_text(systematic: Sequence[dict[str, Any]]) -> str | None:
    """``Systematic error: answered GT + 4 on 50 of 50 answered images`` (several joined
    with ``;``), or ``None`` when there is none."""
    if not systematic:
        return None
    return "Systematic error: " + "; ".join(s["text"] for s in systematic)


def strongest_cause_text(causes: Sequence[dict[str, Any]]) -> str:
    """``Strongest cause: ...`` when the top cause's p value is below :data:`CAUSE_P_VALUE`,
    else a line saying that no parameter separates the failures clearly (and the closest)."""
    if not causes:
        return "No causes ranked (fewer than 2 failing or passing images)"
    if causes[0]["p_value"] < CAUSE_P_VALUE:
        return f"Strongest cause: {cause_sentence(causes[0])}"
    return ("No scene parameter clearly separates the failures from the passes (closest: "
            f"{cause_sentence(causes[0])})")


def cause_sentence(cause: dict[str, Any]) -> str:
    """One line for a ranked cause: ``failures have higher derived.max_aspect_ratio (median
    3.4 vs 1.8 in passes; strength 0.91)``."""
    return (f"failures have {cause['direction']} {cause['param']} (median "
            f"{_fmt(cause['fail_median'])} vs {_fmt(cause['pass_median'])} in passes; strength "
            f"{cause['strength']:.2f}, p {cause['p_value']:.2g})")


#: Breakdown tables a report shows (the rest stay in report.json).
SHOWN_BREAKDOWNS = 4


def shown_breakdown(report: Any, *, limit: int = SHOWN_BREAKDOWNS) -> list[str]:
    """The breakdown parameters a report shows, most telling first: the ranked causes'
    parameters (:func:`rank_causes`), then by pass-rate spread (:func:`importance`)."""
    ranked = [c["param"] for c in report.causes if c["param"] in report.breakdown]
    rest = sorted((k for k in report.breakdown if k not in ranked),
                  key=lambda k: importance(report.breakdown[k]), reverse=True)
    return [*ranked, *rest][:limit]
