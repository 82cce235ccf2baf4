"""Sweep axes (``--vary`` parsing, grid and random points) and breakdown points, on real
harness records."""

import numpy as np
import pytest

from arenabench.eval.scoring.metrics import score_image, summarize
from arenabench.eval.scoring.results import ImageResult, Prediction, Truth
from arenabench.eval.sweep.breakdown import (
    CurvePoint,
    axis_curve,
    axis_groups,
    breakdown_value,
    group_of,
)
from arenabench.eval.sweep.grid import grid_points, parse_varies, parse_vary, random_points


def test_stepped_range_is_inclusive_and_exact():
    axis = parse_vary("camera.tilt_deg=0:40:5")
    assert axis.key == "camera.tilt_deg"
    assert axis.values == (0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0)
    assert not axis.continuous and axis.numeric
    assert parse_vary("lighting.ambient=0.1:0.3:0.1").values == (0.1, 0.2, 0.3)


def test_negative_step_list_and_two_part_range():
    assert parse_vary("obstacles.count=5:1:-2").values == (5, 3, 1)
    assert parse_vary("obstacles.count=3,1,5").values == (3, 1, 5)
    axis = parse_vary("lighting.ambient=0.2:0.6")
    assert axis.values == (0.2, 0.3, 0.4, 0.5, 0.6)
    assert axis.continuous and (axis.lo, axis.hi) == (0.2, 0.6)
    assert parse_vary("arena.texture=plain,speckle").values == ("plain", "speckle")
    assert parse_vary("arena.floor_rgb=250,250,250;200,190,180").values == (
        (250, 250, 250),
        (200, 190, 180),
    )


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("camera.tilt_deg=0:40:-5", "step -5 does not lead from 0 to 40"),
        ("camera.tilt_deg=0:90:10", "out of range"),
        ("camera.tilt_deg=a:b", "'a' is not a number"),
        ("camera.tilt_deg=1:2:3:4", "a range is a:b or a:b:step"),
        ("camera.tilt_deg=5,5", "values repeat"),
        ("obstacles.count=0:3:0.5", "invalid int value"),
        ("arena.texture=plain,marble", "choices"),
        ("camera.tilt_deg=", "empty spec"),
    ],
)
def test_bad_specs_name_key_and_spec(text, needle):
    with pytest.raises(ValueError) as err:
        parse_vary(text)
    message = str(err.value)
    assert message.startswith(f"--vary {text}:"), message
    assert needle in message
    assert "\n" not in message


def test_unknown_parameter_and_duplicates():
    with pytest.raises(ValueError, match=r"--vary camera\.tilt=0:1:1: unknown parameter"):
        parse_vary("camera.tilt=0:1:1")
    with pytest.raises(ValueError, match="expected KEY=SPEC"):
        parse_vary("camera.tilt_deg")
    with pytest.raises(ValueError, match="varied twice"):
        parse_varies(["camera.tilt_deg=0,1", "camera.tilt_deg=2,3"])


def test_grid_first_axis_slowest():
    axes = parse_varies(["camera.tilt_deg=0,20", "obstacles.count=1,2,3"])
    points = grid_points(axes)
    assert len(points) == 6
    assert points[0] == {"camera.tilt_deg": 0.0, "obstacles.count": 1}
    assert points[1] == {"camera.tilt_deg": 0.0, "obstacles.count": 2}
    assert points[3] == {"camera.tilt_deg": 20.0, "obstacles.count": 1}


def test_random_points_seeded_and_within_ranges():
    axes = parse_varies(["camera.tilt_deg=0:40", "obstacles.count=1:5",
                         "arena.texture=plain,speckle", "lighting.ambient=0.2:0.6:0.2"])
    a = random_points(axes, n=50, rng=np.random.default_rng(3))
    b = random_points(axes, n=50, rng=np.random.default_rng(3))
    assert a == b
    tilts = [p["camera.tilt_deg"] for p in a]
    assert min(tilts) >= 0 and max(tilts) <= 40 and len(set(tilts)) == 50
    assert {p["obstacles.count"] for p in a} <= {1, 2, 3, 4, 5}
    assert all(isinstance(p["obstacles.count"], int) for p in a)
    assert {p["arena.texture"] for p in a} == {"plain", "speckle"}
    assert {p["lighting.ambient"] for p in a} <= {0.2, 0.4, 0.6}
    with pytest.raises(ValueError, match="n must be"):
        random_points(axes, n=0, rng=np.random.default_rng(0))


def _results(n_pass: int, n_fail: int) -> list[ImageResult]:
    truth = Truth(count=2, area=1000.0, marker_ids=(80, 85, 90, 95))
    out = []
    for k in range(n_pass + n_fail):
        pred = Prediction(status="ok", count=2 if k < n_pass else 3, area=1000.0,
                          marker_ids=(80, 85, 90, 95))
        out.append(ImageResult(id=str(k), image="", truth=truth, prediction=pred,
                               score=score_image(truth, pred)))
    return out


def _curve(values, groups):
    return [
        CurvePoint(v, str(v), summarize([r.score for r in g], [r.prediction for r in g]))
        for v, g in zip(values, groups, strict=True)
    ]


def test_breakdown_is_contiguous_from_the_easy_end():
    good, bad = _results(100, 0), _results(60, 40)
    # 100/100 has a lower bound of 0.963; 60/100 of 0.50
    curve = _curve([0, 10, 20, 30], [good, good, bad, good])
    assert breakdown_value(curve, threshold=0.9) == 10
    assert breakdown_value(curve, threshold=0.4) == 30
    assert breakdown_value(_curve([0, 10], [bad, good]), threshold=0.9) is None
    # an empty group (every scene skipped) stops the scan
    assert breakdown_value(_curve([0, 10, 20], [good, [], good]), threshold=0.9) == 0
    # 50/50 clears 0.9 (lower bound 0.929), 49/50 does not (0.895)
    assert breakdown_value(_curve([1, 2], [_results(50, 0), _results(49, 1)]),
                           threshold=0.9) == 1


def test_axis_curve_marginal_and_axis_modes():
    axes = parse_varies(["camera.tilt_deg=0,20", "obstacles.count=1,2"])
    points = grid_points(axes)  # (0,1) (0,2) (20,1) (20,2)
    results = {0: _results(10, 0), 1: _results(0, 10), 2: _results(10, 0), 3: _results(0, 10)}
    marginal = axis_curve(axes[0], axes=axes, points=points, results=results, random=False)
    assert [c.summary.n for c in marginal] == [20, 20]
    assert [c.summary.pass_rate for c in marginal] == [0.5, 0.5]
    section = axis_curve(axes[0], axes=axes, points=points, results=results, random=False,
                         mode="axis")
    assert [c.summary.n for c in section] == [10, 10]
    assert [c.summary.pass_rate for c in section] == [1.0, 1.0]


def test_random_continuous_axis_bins_from_the_easy_end():
    axis = parse_vary("camera.tilt_deg=40:0")
    groups = axis_groups(axis, random=True, bins=4)
    assert [g[0] for g in groups] == [35.0, 25.0, 15.0, 5.0]
    assert group_of(axis, 39.0, random=True, bins=4) == 0
    assert group_of(axis, 0.0, random=True, bins=4) == 3
    assert group_of(axis, 40.0, random=True, bins=4) == 0


def test_breakdown_reason_tells_too_few_scenes_from_a_failure():
    from arenabench.eval.sweep.breakdown import breakdown_reason, scenes_needed

    assert scenes_needed(0.9) == 35  # 35/35 has a lower bound of 0.901, 34/34 of 0.898
    assert breakdown_value(_curve([0, 10], [_results(2, 0), _results(2, 0)]),
                           threshold=0.9) is None
    text = breakdown_reason(_curve([0, 10], [_results(2, 0), _results(2, 0)]), threshold=0.9)
    assert text.startswith("cannot be determined with 2 scene(s) at the first value")
    assert "at least 35 passing scenes" in text
    assert breakdown_reason(_curve([0], [_results(1, 9)]), threshold=0.9) == (
        "none (fails at the first value)")
    assert breakdown_reason(_curve([0], [[]]), threshold=0.9) == (
        "none (no scenes at the first value)")
