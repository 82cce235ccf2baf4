"""``junit.xml``: one test case per image, so CI systems show failing images natively."""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

from arenabench.eval.scoring.results import ImageResult, Report
from arenabench.fileio import atomic_write_bytes
from arenabench.jsonstream import atomic_text_writer

_INVALID_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def xml_safe(text: str) -> str:
    """``text`` without the characters XML 1.0 cannot hold (pipelines may print binary)."""
    return _INVALID_XML.sub("\ufffd", text)


def junit_tree(report: Report) -> ET.ElementTree:
    """The JUnit document: a ``testsuite`` of ``testcase`` elements, a ``failure`` element
    (``type`` = category, ``message`` = what was wrong) on each failing image."""
    suites, suite = _suites(report)
    for r in report.images:
        suite.append(_case(report, r))
    ET.indent(suites)
    return ET.ElementTree(suites)


def _suites(report: Report) -> tuple[ET.Element, ET.Element]:
    """The ``testsuites`` element and its ``testsuite`` (with its properties, no cases)."""
    s = report.summary
    failed = s.n - s.n_passed
    total_s = sum(r.prediction.measured_latency_ms or 0.0 for r in report.images) / 1000.0
    suites = ET.Element("testsuites", name="arenabench", tests=str(s.n), failures=str(failed))
    suite = ET.SubElement(
        suites,
        "testsuite",
        name=f"arenabench.eval[{report.pipeline}]",
        tests=str(s.n),
        failures=str(failed),
        errors="0",
        skipped="0",
        time=f"{total_s:.3f}",
    )
    props = ET.SubElement(suite, "properties")
    for key, value in (
        ("dataset", report.dataset),
        ("pipeline", report.pipeline),
        ("area_reference", report.area_reference),
        ("tolerance", str(report.tolerance)),
        ("pass_rate", f"{s.pass_rate:.4f}"),
    ):
        ET.SubElement(props, "property", name=key, value=value)
    return suites, suite


def _case(report: Report, r: ImageResult) -> ET.Element:
    """One image's ``testcase`` element."""
    case = ET.Element(
        "testcase",
        classname=f"arenabench.{Path(report.dataset).name or 'dataset'}",
        name=r.id,
        time=f"{(r.prediction.measured_latency_ms or 0.0) / 1000.0:.3f}",  # none: 0
    )
    if not r.passed:
        p, sc = r.prediction, r.score
        detail = (
            f"gt count {r.truth.count} area {r.truth.area:.1f}; "
            f"pred count {p.count} area {p.area}; area_rel_err {sc.area_rel_err}"
        )
        msg = f"{sc.category}: {p.message or detail}"
        if r.phase is not None:  # the phase check's verdict first: it is cut last
            msg = (f"{r.phase.label.replace('_', '-')} (passes {r.phase.passes}/"
                   f"{r.phase.n} sub-pixel phases{_phase_more(r.phase)}): {msg}")
        fail = ET.SubElement(
            case, "failure", type=str(sc.category), message=xml_safe(msg[:1000])
        )
        fail.text = xml_safe(f"{detail}\nimage: {r.image}")
    if r.prediction.stdout:
        ET.SubElement(case, "system-out").text = xml_safe(r.prediction.stdout)
    if r.prediction.stderr:
        ET.SubElement(case, "system-err").text = xml_safe(r.prediction.stderr)
    return case


#: Stands for the test cases in the serialised skeleton of :func:`write_junit`.
_CASES_MARK = "arenabench-test-cases-go-here"


def write_junit(report: Report, path: str | os.PathLike[str]) -> Path:
    """Write ``junit.xml`` (the test cases serialised one at a time: a run of any size;
    the bytes of ``junit_tree(report)`` serialised whole)."""
    if not len(report.images):
        buf = ET.tostring(junit_tree(report).getroot(), encoding="utf-8", xml_declaration=True)
        return atomic_write_bytes(path, buf + b"\n")
    suites, suite = _suites(report)
    ET.SubElement(suite, _CASES_MARK)
    ET.indent(suites)
    head, mark, tail = ET.tostring(suites, encoding="unicode").partition(f"<{_CASES_MARK} />")
    assert mark, "the skeleton holds the mark"
    with atomic_text_writer(path) as fh:
        fh.write("<?xml version='1.0' encoding='utf-8'?>\n" + head)
        first = True
        for r in report.images:
            case = _case(report, r)
            ET.indent(case, level=2)
            fh.write(("" if first else "\n    ") + ET.tostring(case, encoding="unicode"))
            first = False
        fh.write(tail + "\n")
    return Path(path)


def _phase_more(phase) -> str:
    """What a phase record adds beyond the phases: the open parameters a pass needed, the runs
    that did not complete."""
    more = ""
    if phase.depends_on:
        more += f"; passes with another {', '.join(phase.depends_on)}"
    if missing := phase.total_runs - phase.total_completed:
        more += f"; {missing} of {phase.total_runs} runs did not complete"
    return more
