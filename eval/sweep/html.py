"""``sweep.html``: one self-contained page (inline PNGs, no scripts) with the settings, the
breakdown points, the plots and the per-point table."""

from __future__ import annotations

import base64
import html

from arenabench.generator.parameters.presets import preset_name

from ..reports.html_report import CSS
from ..reports.incomplete import banner_html
from ..scoring.metric_registry import fmt
from .breakdown import breakdown_texts
from .grid import point_label
from .records import SweepResult

#: Extra style of the sweep page: the "clears the threshold, interval does not" colour.
SWEEP_CSS = ".unsure{color:#9a6700}"


def point_class(n: int, pass_rate: float, lower: float, threshold: float) -> str:
    """CSS class of a point's pass rate: ``pass`` (rate and its Wilson lower bound clear
    ``threshold``), ``unsure`` (only the rate does) or ``fail`` (the rate does not, or no
    scenes)."""
    if not n or pass_rate < threshold:
        return "fail"
    return "pass" if lower >= threshold else "unsure"


def sweep_page(result: SweepResult, figures: list[tuple[str, str, bytes]]) -> str:
    """The page as text.

    Parameters
    ----------
    result : SweepResult
    figures : list of (file name, title, png bytes)
        From :func:`arenabench.eval.sweep.plots.sweep_figures`.
    """
    e = html.escape
    spec = result.spec
    d = spec.to_dict()
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<link rel="icon" href="data:,">',
        f"<title>arenabench sweep: {e(preset_name(spec.preset))}</title>"
        f"<style>{CSS}{SWEEP_CSS}</style></head><body>",
        f"<h1>arenabench sweep: preset {e(preset_name(spec.preset))}</h1>",
        "" if result.complete else banner_html(int(result.run.get("samples_done", 0)),
                                               result.run.get("samples")),
        "<table>",
        *(f"<tr><th>{e(k)}</th><td>{e(str(v))}</td></tr>" for k, v in (
            ("mode", d["mode"] + (f" ({spec.random} points)" if spec.random else "")),
            ("varied", "; ".join(f"{a.key} = {a.spec}" for a in spec.axes) or "-"),
            ("fixed (--set)", ", ".join(f"{k}={v}" for k, v in d["set"].items()) or "-"),
            ("points x scenes", f"{len(result.points)} x {spec.per_point} "
                                f"({d['scenes']} scenes, seed {spec.seed})"),
            ("pipelines", ", ".join(p.name for p in spec.pipelines)),
            ("pass", f"count exact and |area_rel_err| <= {spec.tolerance:g} "
                     f"({spec.area_reference} area)"),
            ("run", ", ".join(f"{k} {v}" for k, v in result.run.items()
                              if not isinstance(v, dict))),
        )),
        "</table>",
        "<h2>Breakdown points</h2>",
        f"<p>Furthest value, scanning from the first value given, at which the pass rate's "
        f"lower 95 % Wilson bound is still at least {spec.threshold:g} "
        f"({e(spec.breakdown_mode)} over the other parameters).</p>",
        "<table><tr><th>pipeline</th>",
        *(f"<th>{e(a.key)}</th>" for a in spec.axes),
        "</tr>",
    ]
    for name, texts in breakdown_texts(result).items():
        parts.append(f"<tr><td>{e(name)}</td>")
        parts += [f"<td>{e(texts[a.key])}</td>" for a in spec.axes]
        parts.append("</tr>")
    parts.append('</table><h2>Plots</h2><div class="plots">')
    for _, title, png in figures:
        uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
        parts.append(f'<img alt="{e(title)}" title="{e(title)}" src="{uri}">')
    parts.append("</div><h2>Points</h2>")
    parts.append(
        f'<p>Pass rate colour: <span class="pass">green</span> = the point clears the '
        f"threshold ({spec.threshold:g}) and so does the lower end of its 95 % interval; "
        f'<span class="unsure">amber</span> = the pass rate clears it but the interval\'s '
        f"lower end does not (too few scenes to be sure; breakdown points need the lower end); "
        f'<span class="fail">red</span> = the pass rate is below the threshold.</p>'
    )
    parts.append(
        "<table><tr><th>#</th><th>parameters</th><th>pipeline</th><th>n</th>"
        "<th>pass rate</th><th>95 % CI</th><th>count exact</th><th>|area err| median</th>"
        "<th>|area err| p95</th><th>failures</th><th>skipped</th></tr>"
    )
    for ps in result.summaries:
        s = ps.summary
        lo, hi = s.pass_rate_ci95
        fails = ", ".join(f"{c} {v}" for c, v in s.failures.items() if v) or "-"
        cls = point_class(s.n, s.pass_rate, lo, spec.threshold)
        parts.append(
            f"<tr><td>{ps.index}</td><td>{e(point_label(ps.params))}</td>"
            f"<td>{e(ps.pipeline)}</td><td>{s.n}</td>"
            f'<td class="{cls}">{fmt(s.pass_rate, pct=True)}</td>'
            f"<td>{fmt(lo, pct=True)} - {fmt(hi, pct=True)}</td>"
            f"<td>{fmt(s.count_exact_rate, pct=True)}</td>"
            f"<td>{fmt(s.area_rel_err.get('median'))}</td>"
            f"<td>{fmt(s.area_rel_err.get('p95'))}</td><td>{e(fails)}</td>"
            f"<td>{ps.skipped}</td></tr>"
        )
    parts.append("</table></body></html>")
    return "\n".join(parts) + "\n"
