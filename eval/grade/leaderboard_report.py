"""``leaderboard.json``, ``leaderboard.csv`` and ``leaderboard.html`` of ``arenabench grade``.

All three are written from the ``arenabench.leaderboard/1`` document
(:func:`arenabench.eval.grade.leaderboard.leaderboard_dict`), each atomically. The HTML page is
self-contained (inline style and script, nothing fetched): one row per team with its failure
categories and a link to its report; clicking a column header sorts by it (again: reverse),
and ``leaderboard.html#sort=KEY`` or ``#sort=-KEY`` opens it sorted (``KEY`` is a column's
``data-key``: ``rank``, ``team``, ``pass_rate``, ``count_exact_rate``,
``area_rel_err_median``, ``latency_ms_median``, ``failures_CATEGORY``). Empty values sort last.
"""

from __future__ import annotations

import csv
import html
import io
import os
from pathlib import Path
from typing import Any
from urllib.parse import quote

from arenabench.eval.scoring.metric_registry import METRIC
from arenabench.eval.scoring.phase_summary import PHASE_DEPENDENT_MEANING
from arenabench.fileio import atomic_write_json, atomic_write_text

from ..reports.incomplete import banner_html, partial
from .leaderboard import LEADERBOARD_METRICS

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px;color:#222}
h1{font-size:1.5em}table{border-collapse:collapse;margin:8px 0}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:right;font-size:.9em}
td.team,th.team{text-align:left}th{background:#f3f3f3;cursor:pointer;user-select:none}
th.sorted-asc::after{content:" \\25B2"}th.sorted-desc::after{content:" \\25BC"}
td.zero{color:#bbb}td.fail{color:#b00020}.meta{color:#555;font-size:.9em}
"""

SCRIPT = """
(function(){
  var table=document.getElementById('leaderboard'), body=table.tBodies[0];
  var heads=table.tHead.rows[0].cells, state={key:null,desc:false};
  function head(key){for(var i=0;i<heads.length;i++)
    if(heads[i].getAttribute('data-key')===key)return heads[i]; return null;}
  function val(row,key){var c=row.querySelector('[data-key="'+key+'"]');
    return c?c.getAttribute('data-v'):'';}
  function sortBy(key,desc){
    var h=head(key); if(!h)return;
    var num=h.getAttribute('data-num')==='1';
    var rows=Array.prototype.slice.call(body.rows);
    rows.sort(function(a,b){
      var x=val(a,key),y=val(b,key),r;
      if(x===''||y===''){r=(x==='')-(y==='');}
      else{r=num?parseFloat(x)-parseFloat(y):(x<y?-1:(x>y?1:0)); if(desc)r=-r;}
      return r||(parseFloat(val(a,'rank'))-parseFloat(val(b,'rank')));});
    rows.forEach(function(r){body.appendChild(r);});
    for(var i=0;i<heads.length;i++)heads[i].classList.remove('sorted-asc','sorted-desc');
    h.classList.add(desc?'sorted-desc':'sorted-asc');
    state={key:key,desc:desc};}
  for(var i=0;i<heads.length;i++){heads[i].addEventListener('click',function(){
    var key=this.getAttribute('data-key');
    sortBy(key,state.key===key?!state.desc:this.getAttribute('data-desc')==='1');});}
  var m=/^#sort=(-?)(.+)$/.exec(window.location.hash);
  if(m){sortBy(decodeURIComponent(m[2]),m[1]==='-');}
})();
"""


#: The files :func:`write_leaderboard` writes: JSON, CSV, HTML.
LEADERBOARD_FILES: tuple[str, str, str] = ("leaderboard.json", "leaderboard.csv",
                                           "leaderboard.html")
#: Columns of ``leaderboard.csv``; ``failures_CATEGORY`` columns and ``report`` follow.
#: The pass rate comes first with its interval; the other metric columns are the leaderboard's
#: metrics (:data:`~arenabench.eval.grade.leaderboard.LEADERBOARD_METRICS`) in their order.
CSV_COLUMNS: tuple[str, ...] = (
    "rank", "team", "n", "n_passed", "pass_rate",
    METRIC["pass_rate_ci95.0"].key, METRIC["pass_rate_ci95.1"].key,
    *(m.key for m in LEADERBOARD_METRICS if m.key != "pass_rate"),
)
#: Leading characters by which a spreadsheet reads a cell as a formula (and tab / CR,
#: which some strip first); such text cells get a leading apostrophe in ``leaderboard.csv``.
CSV_FORMULA_STARTS: tuple[str, ...] = ("=", "+", "-", "@", "\t", "\r")
#: Significant digits of floats in ``leaderboard.csv`` (no ``0.9999999999999999``).
CSV_FLOAT_DIGITS = 10


def csv_cell(value: Any) -> Any:
    """One ``leaderboard.csv`` cell: ``None`` empty, floats rounded to
    :data:`CSV_FLOAT_DIGITS` significant digits, text that a spreadsheet would run as a
    formula prefixed with ``'``."""
    if value is None:
        return ""
    if isinstance(value, float):
        return float(f"{value:.{CSV_FLOAT_DIGITS}g}")
    if isinstance(value, str) and value.startswith(CSV_FORMULA_STARTS):
        return "'" + value
    return value


def _fmt(value: Any, kind: str) -> str:
    if value is None:
        return "-"
    if kind == "pct":
        return f"{100.0 * float(value):.1f} %"
    if kind == "pct2":
        return f"{100.0 * float(value):.2f} %"
    if kind == "ms":
        return f"{float(value):.0f}"
    return str(value)


def _cell(key: str, value: Any, text: str, cls: str = "") -> str:
    v = "" if value is None else str(value)
    klass = f' class="{cls}"' if cls else ""
    return (f'<td data-key="{html.escape(key)}" data-v="{html.escape(v)}"{klass}>'
            f"{text}</td>")


def _href(report: str) -> str:
    return "/".join(quote(part) for part in report.split("/"))


def leaderboard_html(doc: dict[str, Any]) -> str:
    """The self-contained HTML page of a leaderboard document."""
    teams = doc["teams"]
    cats = [c for c in doc["categories"] if any(t["failures"].get(c, 0) for t in teams)]
    # (data-key, header, sorts descending on first click)
    cols = [("rank", "Rank", False), ("team", "Team", False), ("pass_rate", "Pass rate", True),
            ("count_exact_rate", "Count exact", True),
            ("area_rel_err_median", "Median |area error|", False),
            ("latency_ms_median", "Median latency (ms)", False)]
    phased = any(t.get("phase_dependent_failure_rate") is not None for t in teams)
    if phased:
        cols[3:3] = [("robust_failure_rate", "Robust failures", False),
                     ("phase_dependent_failure_rate", "Phase-dependent failures", False),
                     ("depends_on_open", "Depend on open parameters", False),
                     ("not_completed", "Phase runs not completed", False)]
    cols += [(f"failures_{c}", c, True) for c in cats]
    head = "".join(
        f'<th data-key="{html.escape(k)}" data-desc="{int(d)}" data-num="{int(k != "team")}"'
        f'{" class=team" if k == "team" else ""}>{html.escape(label)}</th>'
        for k, label, d in cols
    )
    body = []
    for t in teams:
        lo, hi = t["pass_rate_ci95"]
        cells = [
            _cell("rank", t["rank"], f'{t["rank"]}{"=" if t.get("tied") else ""}'),
            _cell("team", t["team"], f'<a href="{html.escape(_href(t["report"]))}">'
                  f'{html.escape(t["team"])}</a>', "team"),
            _cell("pass_rate", t["pass_rate"],
                  f'{_fmt(t["pass_rate"], "pct")} ({t["n_passed"]}/{t["n"]}; 95 % CI '
                  f'{_fmt(lo, "pct")}-{_fmt(hi, "pct")})'),
            *([_cell(k, t.get(k), _fmt(t.get(k), "pct"))
               for k in ("robust_failure_rate", "phase_dependent_failure_rate")]
              if phased else []),
            *([_cell(k, (t.get("phase_check") or {}).get(k),
                     str((t.get("phase_check") or {}).get(k, "-")))
               for k in ("depends_on_open", "not_completed")] if phased else []),
            _cell("count_exact_rate", t["count_exact_rate"],
                  _fmt(t["count_exact_rate"], "pct")),
            _cell("area_rel_err_median", t["area_rel_err_median"],
                  _fmt(t["area_rel_err_median"], "pct2")),
            _cell("latency_ms_median", t["latency_ms_median"],
                  _fmt(t["latency_ms_median"], "ms")),
        ]
        for c in cats:
            n = int(t["failures"].get(c, 0))
            cells.append(_cell(f"failures_{c}", n, str(n), "fail" if n else "zero"))
        body.append("<tr>" + "".join(cells) + "</tr>")
    ds = doc["dataset"]
    opts = doc["options"]
    complete = doc.get("complete", True)
    banner = "" if complete else banner_html(doc.get("images_done", 0), doc.get("images_total"))
    left = doc.get("unfinished") or []
    if left:  # the teams an interrupted grade did not finish, and how far each got
        banner += ('\n<p id="unfinished" class="meta">Not finished (the same command resumes '
                   "from where each stopped): " + ", ".join(
                       f'{html.escape(str(u["team"]))} ({u["images_done"]} of '
                       f'{u["images_total"]} images)' for u in left) + ".</p>")
    box = doc.get("sandbox") or {}
    seen = ", ".join(f"{k} {v}" for k, v in (box.get("versions") or {}).items() if v)
    sandbox = (f' Sandbox {html.escape(str(box.get("mode", "?")))}'
               + (f"; process limit {html.escape(str(box['process_limit']))}"
                  if box.get("process_limit") else "")
               + (f"; seen inside it: {html.escape(seen)}" if seen else "") + "."
               ) if box else ""
    meta = (f'{len(teams)} teams on {html.escape(str(ds["path"]))} ({ds["n"]} images, manifest '
            f'sha256 {html.escape(str(ds["manifest_sha256"])[:12])}); command '
            f'<code>{html.escape(str(opts.get("command", "")))}</code>, tolerance '
            f'{html.escape(str(opts.get("tolerance", "")))}, area reference '
            f'{html.escape(str(opts.get("area_reference", "")))}. Ranked by pass rate, then '
            "count exact rate, then median |area error|; teams equal on all three share a "
            "rank (2=) and are listed by name. Latency is shown, never ranked on; a timed-out "
            "image has none."
            + (f" {html.escape(PHASE_DEPENDENT_MEANING[0].upper() + PHASE_DEPENDENT_MEANING[1:])}."
               if phased else "") + sandbox)
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        "<title>arenabench leaderboard</title>"
        f"<style>{CSS}</style></head><body>\n<h1>{partial('Leaderboard', complete)}</h1>\n"
        f"{banner}\n"
        f'<p class="meta">{meta}</p>\n'
        f'<table id="leaderboard"><thead><tr>{head}</tr></thead>\n<tbody>\n'
        + "\n".join(body)
        + f"\n</tbody></table>\n<script>{SCRIPT}</script>\n</body></html>\n"
    )


def leaderboard_csv(doc: dict[str, Any]) -> str:
    """``leaderboard.csv``: one row per team, in rank order."""
    cats = list(doc["categories"])
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow([*CSV_COLUMNS, *(f"failures_{c}" for c in cats), "report"])
    for t in doc["teams"]:
        lo, hi = t["pass_rate_ci95"]
        row = [t["rank"], t["team"], t["n"], t["n_passed"], t["pass_rate"], lo, hi,
               *(t.get(m.key) for m in LEADERBOARD_METRICS if m.key != "pass_rate")]
        row += [t["failures"].get(c, 0) for c in cats] + [t["report"]]
        writer.writerow([csv_cell(v) for v in row])
    return buf.getvalue()


def write_leaderboard(doc: dict[str, Any], out_dir: str | os.PathLike[str]) -> dict[str, Path]:
    """Write the three leaderboard files (:data:`LEADERBOARD_FILES`) into ``out_dir``; returns
    name -> path."""
    out = Path(out_dir)
    json_name, csv_name, html_name = LEADERBOARD_FILES
    return {
        json_name: atomic_write_json(out / json_name, doc),
        csv_name: atomic_write_text(out / csv_name, leaderboard_csv(doc)),
        html_name: atomic_write_text(out / html_name, leaderboard_html(doc)),
    }
