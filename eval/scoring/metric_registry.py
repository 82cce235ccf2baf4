"""The metric registry: one declaration per summary metric of ``report.json``.

Every metric a summary holds is one :class:`Metric` in :data:`METRICS`, named by its dotted path
in the ``summary`` object (``pass_rate``, ``pass_rate_ci95.0``, ``area_rel_err.p95``,
``failures.crash``). Everything else is derived from it: the ``--fail-under`` names and whether
each is a minimum or a maximum (:mod:`arenabench.eval.scoring.thresholds`), the metrics
``--compare`` lists and ``--fail-on-regression`` judges, and which way is better
(:mod:`arenabench.eval.scoring.compare`), the summary rows of the Markdown/HTML reports and the CLI
(:mod:`arenabench.eval.reports.summary_rows`), the metric columns of ``sweep.csv``
(:func:`column_metrics`), the leaderboard's metric columns
(:mod:`arenabench.eval.grade.leaderboard`) and the metrics table of docs/formats.md
(:func:`metrics_table_markdown`).

To add a metric: compute it into :class:`~arenabench.eval.scoring.results.Summary` (and its
``to_dict``), then add one :class:`Metric` here.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .results import CATEGORIES

#: Which way a metric is better: larger, smaller, or nearer zero (signed errors).
DIRECTIONS: tuple[str, ...] = ("higher", "lower", "nearer_zero")
#: Kinds of value: a fraction shown as %, a count, pixels, milliseconds, a plain ratio.
KINDS: tuple[str, ...] = ("rate", "count", "px", "ms", "ratio")
#: Where the summary shows a metric: the main rows, the phase check's rows, the failure rows.
GROUPS: tuple[str, ...] = ("summary", "phase", "failures")
#: The values a metric of each kind can take, and so the ``--fail-under`` limits and
#: ``--fail-on-regression`` deltas it accepts: a rate is a fraction in [0, 1] (``0.95``, not
#: ``95``); counts, pixels, milliseconds and error ratios are >= 0 (the limit of a signed
#: error is on its magnitude).
KIND_RANGES: dict[str, tuple[float, float]] = {
    "rate": (0.0, 1.0), "count": (0.0, math.inf), "px": (0.0, math.inf),
    "ms": (0.0, math.inf), "ratio": (0.0, math.inf),
}


@dataclass(frozen=True)
class Metric:
    """One summary metric.

    Parameters
    ----------
    name : str
        Dotted path in ``report.json``'s ``summary`` (list items by index:
        ``pass_rate_ci95.0``); also its ``--fail-under`` / ``--fail-on-regression`` name.
    label : str
        Short human label.
    direction : {"higher", "lower", "nearer_zero"}
        Which way is better.
    kind : {"rate", "count", "px", "ms", "ratio"}
        What the value is; a ``rate`` is shown as a percentage.
    row : str
        The summary row that shows it; metrics sharing a row are shown together, in
        registry order, joined by :data:`ROW_SEPARATORS` (default ``" / "``).
    group : {"summary", "phase", "failures"}
        The part of the summary it belongs to.
    digits : int
        Significant digits when not a rate.
    flat : str
        Its CSV column name when not the dotted name with ``_`` for ``.`` (:attr:`key`).
    column : bool
        Whether flat tables of many summaries (``sweep.csv``) give it a column
        (:func:`column_metrics`).
    """

    name: str
    label: str
    direction: str
    kind: str
    row: str
    group: str = "summary"
    digits: int = 4
    flat: str = ""
    column: bool = True

    def __post_init__(self) -> None:
        if self.direction not in DIRECTIONS:
            raise ValueError(f"{self.name}: direction must be one of {DIRECTIONS}")
        if self.kind not in KINDS:
            raise ValueError(f"{self.name}: kind must be one of {KINDS}")
        if self.group not in GROUPS:
            raise ValueError(f"{self.name}: group must be one of {GROUPS}")

    @property
    def key(self) -> str:
        """The flat spelling (``area_rel_err_median``) of CSV and leaderboard columns."""
        return self.flat or self.name.replace(".", "_")

    @property
    def minimum(self) -> bool:
        """Whether a ``--fail-under`` limit is a minimum (else a maximum; of ``|value|`` for
        a signed metric)."""
        return self.direction == "higher"

    @property
    def limits(self) -> tuple[float, float]:
        """The range of a limit (or a delta) on this metric: :data:`KIND_RANGES` of its kind."""
        return KIND_RANGES[self.kind]

    def check_limit(self, raw: str, *, option: str, named: bool = True) -> float:
        """``raw`` (what follows ``metric=`` in ``option``; with ``named=False`` the option's
        whole value, as ``check --min-pass-rate 0.9``) as a limit this metric can reach.

        Raises
        ------
        ValueError
            One line naming ``option``, the metric and the value: not a plain decimal number
            (:func:`arenabench.plain_numbers.plain_number`), or outside :attr:`limits` (a rate given
            as a percentage gets its fraction as a hint).
        """
        from arenabench.plain_numbers import plain_number

        lo, hi = self.limits
        what = "a fraction in [0, 1]" if self.kind == "rate" else "a finite number >= 0"
        shown = f"{option} {self.name}={raw}" if named else f"{option} {raw}"
        try:
            value = plain_number(raw.strip(" "))
        except ValueError:
            raise ValueError(f"{shown}: not a number ({what})") from None
        if not (math.isfinite(value) and lo <= value <= hi):
            hint = (f"; {value:g} % is {value / 100:g}"
                    if self.kind == "rate" and 1 < value <= 100 else "")
            raise ValueError(f"{shown}: must be {what}{hint}")
        return value

    def format(self, value: Any) -> str:
        """Human form of ``value`` (``-`` for missing; rates as ``12.3 %``)."""
        if value is None:
            return "-"
        if isinstance(value, float):
            if self.kind == "rate":
                return f"{100 * value:.1f} %"
            return f"{value:.{self.digits}g}"
        return str(value)

    def worsening(self, old: float, new: float) -> float:
        """How much worse ``new`` is than ``old`` (negative when better)."""
        if self.direction == "higher":
            return old - new
        if self.direction == "lower":
            return new - old
        return abs(new) - abs(old)

    def value(self, summary: Mapping[str, Any]) -> Any:
        """This metric's value in a summary dict (``None`` when absent)."""
        return lookup(summary, self.name)


def lookup(summary: Mapping[str, Any], dotted: str) -> Any:
    """Value at ``dotted`` (``"area_rel_err.p95"``, ``"pass_rate_ci95.0"``) in a summary dict,
    ``None`` if absent."""
    node: Any = summary
    for part in dotted.split("."):
        if isinstance(node, Mapping) and part in node:
            node = node[part]
        elif isinstance(node, (list, tuple)) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        else:
            return None
    return node


_AREA = "|area rel err| median / p95 / max"
_SIGNED = "signed area rel err median / p5 / p95"
_SIGNED_EXTREMES = "signed area rel err min / max"
_CI = "pass rate 95 % CI (Wilson)"
_LATENCY = "latency ms median / p95"

#: Every summary metric, in the order reports list them.
METRICS: tuple[Metric, ...] = (
    Metric("pass_rate", "pass rate", "higher", "rate", "pass rate"),
    Metric("pass_rate_ci95.0", "pass rate 95 % CI low", "higher", "rate", _CI,
           flat="pass_rate_ci95_lo"),
    Metric("pass_rate_ci95.1", "pass rate 95 % CI high", "higher", "rate", _CI,
           flat="pass_rate_ci95_hi"),
    Metric("count_exact_rate", "count exact rate", "higher", "rate", "count exact rate"),
    Metric("count_mae", "count MAE", "lower", "count", "count MAE"),
    Metric("area_rel_err.median", "|area rel err| median", "lower", "ratio", _AREA),
    Metric("area_rel_err.p95", "|area rel err| p95", "lower", "ratio", _AREA),
    Metric("area_rel_err.max", "|area rel err| max", "lower", "ratio", _AREA),
    Metric("area_rel_err_signed.median", "signed area rel err median", "nearer_zero", "ratio",
           _SIGNED, column=False),
    Metric("area_rel_err_signed.p5", "signed area rel err p5", "nearer_zero", "ratio", _SIGNED,
           column=False),
    Metric("area_rel_err_signed.p95", "signed area rel err p95", "nearer_zero", "ratio",
           _SIGNED, column=False),
    Metric("area_rel_err_signed.min", "signed area rel err min", "nearer_zero", "ratio",
           _SIGNED_EXTREMES, column=False),
    Metric("area_rel_err_signed.max", "signed area rel err max", "nearer_zero", "ratio",
           _SIGNED_EXTREMES, column=False),
    Metric("marker_id_accuracy", "marker id accuracy", "higher", "rate", "marker id accuracy"),
    Metric("latency_ms.median", "latency median (ms)", "lower", "ms", _LATENCY, digits=3),
    Metric("latency_ms.p95", "latency p95 (ms)", "lower", "ms", _LATENCY, digits=3),
    Metric("robust_failure_rate", "robust failure rate", "lower", "rate",
           "robust failures (fail at every phase)", group="phase", column=False),
    Metric("phase_dependent_failure_rate", "phase-dependent failure rate", "lower", "rate",
           "phase-dependent failures", group="phase", column=False),
    *(Metric(f"failures.{c}", f"failures: {c}", "lower", "count", f"failures: {c}",
             group="failures") for c in CATEGORIES),
)

#: Separators of the values of a summary row other than ``" / "``.
ROW_SEPARATORS: dict[str, str] = {_CI: " - "}

#: Metric by name.
METRIC: dict[str, Metric] = {m.name: m for m in METRICS}

#: The metrics ``--compare`` lists, ``--fail-on-regression`` and ``--fail-under`` accept:
#: every metric except the upper end of the pass rate's interval (not a goal).
GATED: tuple[Metric, ...] = tuple(m for m in METRICS if m.name != "pass_rate_ci95.1")


def metric(name: str) -> Metric:
    """The metric called ``name``.

    Raises
    ------
    KeyError
        Naming the unknown metric.
    """
    try:
        return METRIC[name]
    except KeyError:
        raise KeyError(f"unknown metric {name!r}") from None


def column_metrics(metrics: Sequence[Metric] = METRICS) -> tuple[Metric, ...]:
    """The metrics of flat tables of many summaries (``sweep.csv``), in column order: those
    with :attr:`Metric.column`, in registry order by group, timings (kind ``ms``) last."""
    chosen = [m for m in metrics if m.column]
    return tuple(sorted(chosen, key=lambda m: (m.kind == "ms", GROUPS.index(m.group))))


def summary_row_groups(group: str) -> list[tuple[str, tuple[Metric, ...]]]:
    """The summary rows of ``group``: (row label, its metrics) in registry order."""
    rows: dict[str, list[Metric]] = {}
    for m in METRICS:
        if m.group == group:
            rows.setdefault(m.row, []).append(m)
    return [(row, tuple(ms)) for row, ms in rows.items()]


def names_by_direction(direction: str) -> str:
    """The gated metrics of ``direction`` for help texts: members of one object joined
    (``area_rel_err.median|p95|max``), the failure counts as ``failures.<category>``."""
    groups: dict[str, list[str]] = {}
    for m in GATED:
        if m.direction != direction:
            continue
        if m.group == "failures":
            groups.setdefault("failures.<category>", [])
        elif "." in m.name:
            head, _, tail = m.name.rpartition(".")
            groups.setdefault(head + ".", []).append(tail)
        else:
            groups.setdefault(m.name, [])
    return ", ".join(head + "|".join(tails) for head, tails in groups.items())


def fail_under_help() -> str:
    """The ``--fail-under`` paragraph of ``arenabench eval --help``."""
    return (
        "--fail-under metric=value (comma-separated or repeated). Minimums (fail when below): "
        f"{names_by_direction('higher')}. Maximums (fail when above): "
        f"{names_by_direction('lower')}; of the magnitude: {names_by_direction('nearer_zero')}."
    )


def metrics_table_markdown() -> str:
    """The Markdown table of every metric (docs/formats.md holds it verbatim)."""
    lines = ["| metric | label | better | kind |", "|---|---|---|---|"]
    better = {"higher": "higher", "lower": "lower", "nearer_zero": "nearer 0"}
    for m in METRICS:
        label = m.label.replace("|", "\\|")
        lines.append(f"| `{m.name}` | {label} | {better[m.direction]} | {m.kind} |")
    return "\n".join(lines) + "\n"


def split_metric_specs(specs: Iterable[str], *, option: str, known: Sequence[str],
                       what: str = "value") -> list[tuple[str, str]]:
    """``metric=VALUE`` specs (each may hold several, comma-separated) as (metric, raw value)
    pairs, for ``--fail-under`` and ``--fail-on-regression`` alike; the value's own rule is the
    caller's (:meth:`Metric.check_limit`).

    Raises
    ------
    ValueError
        Naming ``option`` and the part without ``=``, the unknown metric (with a "did you
        mean" hint), or a metric given twice.
    """
    from arenabench.suggest import did_you_mean

    out = []
    seen: dict[str, str] = {}
    for spec in specs:
        for part in filter(None, (p.strip() for p in spec.split(","))):
            name, sep, raw = part.partition("=")
            name = name.strip()
            if not sep:
                raise ValueError(f"{option} expects metric={what}, got {part!r}")
            if name not in known:
                hint = did_you_mean(name, known) or f" (known: {', '.join(known)})"
                raise ValueError(f"{option}: unknown metric {name!r}{hint}")
            if name in seen:
                raise ValueError(f"{option}: {name} given twice ({seen[name]!r} and {part!r}): "
                                 "give each metric once")
            seen[name] = part
            out.append((name, raw))
    return out


def fmt(value: object, *, pct: bool = False, digits: int = 4) -> str:
    """Human form of a metric value (``-`` for missing)."""
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{100 * value:.1f} %" if pct else f"{value:.{digits}g}"
    return str(value)
