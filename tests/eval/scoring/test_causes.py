"""Causes: scene parameters ranked by how well they separate failures from passes
(eval/breakdown.py rank_causes), on hand-made results and on a real twin run."""

from __future__ import annotations

import json

import edge_phase
import pytest
from paths import TESTS

from arenabench.eval.scoring.breakdown import rank_causes
from arenabench.eval.scoring.results import ImageResult, ImageScore, Prediction, Truth


def _result(i: int, passed: bool, **params: float) -> ImageResult:
    return ImageResult(
        id=f"{i:06d}", image="", truth=Truth(count=1, area=1.0),
        prediction=Prediction(status="ok", count=1, area=1.0),
        score=ImageScore(passed=passed, category=None if passed else "wrong_count",
                         count_err=0, area_rel_err=0.0, area_err_kind="relative",
                         marker_ids_ok=None),
        params=dict(params))


def test_auc_strength_direction_and_order():
    results = [
        # 'ratio' separates perfectly (failures higher), 'noise' not at all, 'gap' half way
        _result(0, False, ratio=4.0, noise=1.0, gap=1.0, const=5.0),
        _result(1, False, ratio=3.5, noise=2.0, gap=3.0, const=5.0),
        _result(2, True, ratio=1.0, noise=1.0, gap=2.0, const=5.0),
        _result(3, True, ratio=2.0, noise=2.0, gap=4.0, const=5.0),
    ]
    causes = rank_causes(results)
    assert [c["param"] for c in causes] == ["ratio", "gap", "noise"]  # 'const' left out
    ratio, gap, noise = causes
    assert ratio["auc"] == 1.0 and ratio["strength"] == 1.0 and ratio["direction"] == "higher"
    # gap: pairs (fail, pass) 1<2, 1<4, 3>2, 3<4 -> P(fail > pass) = 1/4
    assert gap["auc"] == 0.25 and gap["strength"] == 0.5 and gap["direction"] == "lower"
    assert noise["auc"] == 0.5 and noise["strength"] == 0.0  # ties count a half
    assert ratio["fail_median"] == 3.75 and ratio["pass_median"] == 1.5
    assert ratio["n_fail"] == 2 and ratio["n_pass"] == 2
    assert 0 < ratio["p_value"] < noise["p_value"] == 1.0
    assert rank_causes(results, top=1) == [ratio]


def test_too_few_failures_rank_nothing():
    results = [_result(0, False, x=1.0), *(_result(i, True, x=float(i)) for i in range(1, 5))]
    assert rank_causes(results) == []


@pytest.mark.integration
def test_an_aspect_ratio_filter_is_traced_to_the_boxes_aspect(shared_sets, tmp_path):
    from arenabench.eval.evaluation import evaluate

    twin = shared_sets.generated("eyrc", count=60, seed=0, workers=2)
    report = evaluate(edge_phase.aspect_filter, twin, workers=2)
    assert 0.8 < report.summary.pass_rate < 1.0
    top = report.causes[0]
    assert top["param"] in ("derived.max_visible_aspect_ratio", "derived.max_aspect_ratio")
    assert top["direction"] == "higher" and top["strength"] > 0.8 and top["p_value"] < 0.01
    md = (tmp_path / "report.md")
    from arenabench.eval.reports import write_reports

    write_reports(report, tmp_path, formats=("md",))
    assert f"Strongest cause: failures have higher {top['param']}" in md.read_text()


def _answered(i: int, count_err: int, area_ratio: float = 1.0) -> ImageResult:
    gt_count, gt_area = 2, 1000.0
    ok = count_err == 0 and abs(area_ratio - 1.0) <= 0.05
    return ImageResult(
        id=f"{i:06d}", image="", truth=Truth(count=gt_count, area=gt_area),
        prediction=Prediction(status="ok", count=gt_count + count_err,
                              area=gt_area * area_ratio),
        score=ImageScore(passed=ok, category=None if ok else "wrong_count",
                         count_err=count_err, area_rel_err=area_ratio - 1.0,
                         area_err_kind="relative", marker_ids_ok=None))


def test_a_count_offset_on_most_images_is_systematic():
    from arenabench.eval.scoring.breakdown import systematic_errors, systematic_text

    results = [_answered(i, 4) for i in range(50)]
    (found,) = systematic_errors(results, tolerance=0.05)
    assert found["kind"] == "count_offset" and found["offset"] == 4
    assert (found["n"], found["of"]) == (50, 50)
    assert systematic_text([found]) == ("Systematic error: answered GT + 4 on 50 of 50 "
                                        "answered images")
    # one short on 9 of 200: a failure mode, not a systematic offset
    results = [_answered(i, -1 if i < 9 else 0) for i in range(200)]
    assert systematic_errors(results, tolerance=0.05) == []
    # crashes are not answers: 3 of 3 answered images are off by -2
    crash = ImageResult(id="x", image="", truth=Truth(count=1, area=1.0),
                        prediction=Prediction(status="crash"),
                        score=ImageScore(passed=False, category="crash", count_err=None,
                                         area_rel_err=None, area_err_kind="relative",
                                         marker_ids_ok=None))
    (found,) = systematic_errors([crash] * 5 + [_answered(i, -2) for i in range(3)],
                                 tolerance=0.05)
    assert found["text"] == "answered GT - 2 on 3 of 3 answered images"


def test_an_area_factor_on_most_images_is_systematic():
    from arenabench.eval.scoring.breakdown import systematic_errors

    results = [_answered(i, 0, 1.21 + 0.001 * (i % 5)) for i in range(10)]
    (found,) = systematic_errors(results, tolerance=0.05)
    assert found["kind"] == "area_factor" and abs(found["factor"] - 1.212) < 0.01
    assert found["text"].startswith("answered an area of GT x 1.21 on 10 of 10")
    # scattered errors have no factor
    scattered = [_answered(i, 0, r) for i, r in enumerate((0.5, 0.8, 1.3, 1.6, 2.0, 0.7))]
    assert systematic_errors(scattered, tolerance=0.05) == []


def test_gt_facts_are_read_from_the_ground_truth(shared_sets):
    from arenabench.eval.datasets.reader import load_dataset
    from arenabench.eval.scoring.gt_facts import FACTS, gt_facts

    for item in load_dataset(shared_sets.generated("eyrc", count=3, seed=0)).samples:
        facts = gt_facts(item.gt)
        assert set(facts) == set(FACTS)
        counted = [o for o in item.gt.obstacles if o.footprint_area_px > 0]
        assert item.gt.count == len(counted)
        assert facts["gt.min_box_visible_px"] == min(o.visible_area_px for o in counted)
        # inner corners: the markers lie outside the frame, the boxes inside
        assert 0 < facts["gt.min_marker_gap_px"] < 1000
    from dataclasses import replace

    empty = replace(item.gt, count=0, obstacles=())
    assert gt_facts(empty) == {}


@pytest.fixture(scope="module")
def twin40(shared_sets):
    return shared_sets.generated("eyrc", count=40, seed=0, workers=2)


@pytest.mark.integration
def test_a_minimum_area_script_is_traced_to_the_smallest_box(twin40, tmp_path):
    """A team script dropping contours under 26000 px: its failures have the smaller
    smallest boxes (a GT fact), not another aspect of the scene."""
    import sys

    from arenabench.eval.evaluation import evaluate
    from arenabench.eval.reports import write_reports
    from arenabench.eval.runs import CommandPipeline

    script = TESTS / "pipelines" / "style_min_area.py"
    report = evaluate(CommandPipeline(f"{sys.executable} {script} --image {{image}}"),
                      twin40, workers=2)
    assert 0.3 < report.summary.pass_rate < 0.95
    assert set(report.summary.failures) >= {"wrong_count"}
    top = report.causes[0]
    assert top["param"] == "gt.min_box_visible_px", report.causes[:3]
    assert top["direction"] == "lower" and top["strength"] > 0.9 and top["p_value"] < 0.01
    assert report.systematic == ()  # one box short on some images: not an offset of all
    write_reports(report, tmp_path, formats=("md",))
    assert ("Strongest cause: failures have lower gt.min_box_visible_px"
            in (tmp_path / "report.md").read_text())


@pytest.mark.integration
def test_counting_the_markers_as_obstacles_is_named_as_an_offset(shared_sets, tmp_path):
    """The seed profile on eyrc-upright counts the four markers as obstacles: every answer is
    GT + 4, every image fails alike, and no scene fact can separate them."""
    from arenabench.eval.commands.check import verdict_lines
    from arenabench.eval.evaluation import evaluate
    from arenabench.eval.reports import write_reports
    up = shared_sets.generated("eyrc-upright", count=8, seed=0, workers=2)
    report = evaluate("seed", up, workers=2)
    assert report.summary.n_passed == 0 and report.causes == ()
    text = "answered GT + 4 on 8 of 8 answered images"
    assert [s["text"] for s in report.systematic if s["kind"] == "count_offset"] == [text]
    lines = verdict_lines(report, min_pass_rate=0.95, phases=0)
    assert f"  systematic error: {text}" in lines
    write_reports(report, tmp_path / "out", formats=("md", "html", "json"))
    for name in ("report.md", "report.html"):
        assert f"Systematic error: {text}" in (tmp_path / "out" / name).read_text()
    doc = json.loads((tmp_path / "out" / "report.json").read_text())
    assert doc["systematic"][0]["offset"] == 4
