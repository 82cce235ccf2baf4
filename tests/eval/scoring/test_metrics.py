"""The evaluator's pure metric functions: perfect, noisy, empty and failing predictions."""

import numpy as np
import pytest

from arenabench.eval.scoring.metrics import score_image, summarize, wilson_interval
from arenabench.eval.scoring.results import CATEGORIES, Prediction, Truth

IDS = (80, 85, 90, 95)


def _truths(rng, n=50):
    return [
        Truth(count=int(c), area=float(a), marker_ids=IDS)
        for c, a in zip(rng.integers(0, 6, n), rng.uniform(1e3, 9e4, n), strict=True)
    ]


def _as_prediction(t: Truth, **kw) -> Prediction:
    base = dict(status="ok", count=t.count, area=t.area, marker_ids=t.marker_ids, latency_ms=5.0)
    base.update(kw)
    return Prediction(**base)


def test_ground_truth_fed_back_scores_perfectly():
    truths = _truths(np.random.default_rng(0))
    preds = [_as_prediction(t) for t in truths]
    scores = [score_image(t, p) for t, p in zip(truths, preds, strict=True)]
    assert all(s.passed and s.category is None for s in scores)
    s = summarize(scores, preds)
    assert (s.n, s.pass_rate, s.count_exact_rate, s.count_mae) == (50, 1.0, 1.0, 0.0)
    assert s.area_rel_err == {"median": 0.0, "p95": 0.0, "max": 0.0}
    assert s.marker_id_accuracy == 1.0
    assert sum(s.failures.values()) == 0 and set(s.failures) == set(CATEGORIES)
    assert s.latency_ms == {"median": 5.0, "p95": 5.0}
    assert s.pass_rate_ci95[1] == 1.0 and 0.9 < s.pass_rate_ci95[0] < 1.0


def test_ground_truth_plus_noise_scores_lower():
    rng = np.random.default_rng(1)
    truths = _truths(rng)
    preds = []
    for t in truths:
        noisy_area = t.area * (1 + rng.normal(0, 0.06))
        noisy_count = max(0, t.count + int(rng.choice([0, 0, 0, 1, -1])))
        preds.append(_as_prediction(t, count=noisy_count, area=noisy_area))
    scores = [score_image(t, p) for t, p in zip(truths, preds, strict=True)]
    s = summarize(scores, preds)
    assert 0.0 < s.pass_rate < 1.0
    assert s.count_exact_rate < 1.0 and s.count_mae > 0
    assert 0 < s.area_rel_err["median"] <= s.area_rel_err["p95"] <= s.area_rel_err["max"]
    assert s.area_rel_err_signed["min"] < 0 < s.area_rel_err_signed["max"]
    assert s.failures["wrong_count"] > 0 and s.failures["area_off"] > 0
    # precedence: a wrong count is reported as wrong_count even when the area is off too
    for sc in scores:
        if sc.count_err != 0:
            assert sc.category == "wrong_count"
        elif abs(sc.area_rel_err) > 0.05:
            assert sc.category == "area_off"


def test_empty_ground_truth_uses_absolute_px_error():
    truth = Truth(count=0, area=0.0, marker_ids=IDS)
    ok = score_image(truth, _as_prediction(truth))
    assert ok.passed and ok.area_err_kind == "absolute_px" and ok.area_rel_err == 0.0
    off = score_image(truth, _as_prediction(truth, area=120.0))
    assert (off.passed, off.category, off.area_rel_err) == (False, "area_off", 120.0)
    s = summarize([ok, off], [_as_prediction(truth), _as_prediction(truth, area=120.0)])
    # absolute-px errors do not pollute the relative statistics
    assert s.area_rel_err["median"] is None and s.pass_rate == 0.5


def test_empty_predictions_and_failed_runs():
    truth = Truth(count=2, area=5000.0, marker_ids=IDS)
    zero = score_image(truth, _as_prediction(truth, count=0, area=0.0, marker_ids=()))
    assert (zero.category, zero.count_err, zero.area_rel_err, zero.marker_ids_ok) == (
        "wrong_count",
        -2,
        -1.0,
        False,
    )
    for status in ("crash", "timeout", "bad_output", "markers_not_found"):
        sc = score_image(truth, Prediction(status=status, message="x"))
        assert (sc.passed, sc.category, sc.count_err, sc.area_rel_err) == (
            False,
            status,
            None,
            None,
        )
        assert sc.marker_ids_ok is False
    # markers_not_found with a well-formed zero answer still counts as markers_not_found
    mnf = score_image(truth, Prediction(status="markers_not_found", count=0, area=0.0))
    assert mnf.category == "markers_not_found"
    # an ok status without a count or area is bad output
    assert score_image(truth, Prediction(status="ok", count=2)).category == "bad_output"
    # no ids reported -> id check not applicable
    assert score_image(truth, _as_prediction(truth, marker_ids=None)).marker_ids_ok is None
    s = summarize([], [])
    assert (s.n, s.pass_rate, s.count_mae, s.marker_id_accuracy) == (0, 0.0, None, None)
    assert s.pass_rate_ci95 == (0.0, 1.0)


def test_marker_ids_compared_as_sets_against_ids_in_view():
    truth = Truth(count=1, area=100.0, marker_ids=(80, 85, 90))
    assert score_image(truth, _as_prediction(truth, marker_ids=(90, 80, 85))).marker_ids_ok
    assert not score_image(truth, _as_prediction(truth, marker_ids=IDS)).marker_ids_ok


def test_tolerance_boundary_and_bad_tolerance():
    truth = Truth(count=1, area=1000.0)
    assert score_image(truth, _as_prediction(truth, area=1050.0), tolerance=0.05).passed
    assert not score_image(truth, _as_prediction(truth, area=1050.5), tolerance=0.05).passed
    with pytest.raises(ValueError, match="tolerance"):
        score_image(truth, _as_prediction(truth), tolerance=-1)


@pytest.mark.parametrize(
    "k, n, lo, hi",
    [
        (0, 10, 0.0, 0.2775),
        (10, 10, 0.7225, 1.0),
        (5, 10, 0.2366, 0.7634),
        (97, 100, 0.9154, 0.9897),
    ],
)
def test_wilson_interval_known_values(k, n, lo, hi):
    got = wilson_interval(k, n)
    assert got == pytest.approx((lo, hi), abs=1e-4)


def test_wilson_rejects_bad_counts():
    with pytest.raises(ValueError, match="successes"):
        wilson_interval(5, 3)


def test_prediction_rejects_unknown_status():
    with pytest.raises(ValueError, match="status"):
        Prediction(status="fine")


def test_wilson_interval_reaches_its_ends_exactly():
    from arenabench.eval.scoring.metrics import wilson_interval

    for n in (1, 3, 7, 200):
        assert wilson_interval(0, n)[0] == 0.0 and wilson_interval(n, n)[1] == 1.0
        assert 0.0 < wilson_interval(0, n)[1] < 1.0 and 0.0 < wilson_interval(n, n)[0] < 1.0
