"""Causes: scene parameters ranked by how well they separate failures from passes
(eval/breakdown.py rank_causes), on hand-made results and on a real twin run."""

from __future__ import annotations

import edge_phase
import pytest

from arenabench.eval.breakdown import rank_causes
from arenabench.eval.results import ImageResult, ImageScore, Prediction, Truth


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


@pytest.mark.slow
def test_an_aspect_ratio_filter_is_traced_to_the_boxes_aspect(tmp_path):
    from arenabench.eval.evaluation import evaluate
    from arenabench.generator.dataset_writer import generate_dataset

    generate_dataset(tmp_path / "twin", preset="eyrc", count=60, seed=0, workers=1,
                     progress=False)
    report = evaluate(edge_phase.aspect_filter, tmp_path / "twin", workers=2)
    assert 0.8 < report.summary.pass_rate < 1.0
    top = report.causes[0]
    assert top["param"] in ("derived.max_visible_aspect_ratio", "derived.max_aspect_ratio")
    assert top["direction"] == "higher" and top["strength"] > 0.8 and top["p_value"] < 0.01
    md = (tmp_path / "report.md")
    from arenabench.eval.reports import write_reports

    write_reports(report, tmp_path, formats=("md",))
    assert f"Strongest cause: failures have higher {top['param']}" in md.read_text()
