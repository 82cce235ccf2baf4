"""Records to and from their JSON form field by field (arenabench.records), and the records
that use it keeping their documented forms."""

import json
from dataclasses import dataclass, field

import pytest

from arenabench.eval.scoring.results import Summary
from arenabench.records import from_plain, to_plain


@dataclass(frozen=True)
class Inner:
    name: str
    sides: tuple[float, float]


@dataclass(frozen=True)
class Outer:
    n: int
    inner: Inner
    rate: float | None
    counts: dict[str, int]
    ids: tuple[int, ...] = ()
    notes: list[str] = field(default_factory=list)


def test_a_record_goes_to_json_and_back_unchanged():
    record = Outer(n=3, inner=Inner("a", (1.0, 2.5)), rate=None, counts={"x": 2}, ids=(4, 5),
                   notes=["y"])
    plain = to_plain(record)
    assert list(plain) == ["n", "inner", "rate", "counts", "ids", "notes"]
    assert plain["inner"] == {"name": "a", "sides": [1.0, 2.5]} and plain["ids"] == [4, 5]
    assert from_plain(Outer, json.loads(json.dumps(plain))) == record


def test_values_take_their_fields_types_and_missing_ones_their_defaults():
    got = from_plain(Outer, {"n": 2.0, "inner": {"name": "b", "sides": [1, 2]}, "rate": 1,
                             "counts": {"x": 1.0}})
    assert got == Outer(n=2, inner=Inner("b", (1.0, 2.0)), rate=1.0, counts={"x": 1})
    assert type(got.rate) is float and type(got.inner.sides[0]) is float


@pytest.mark.parametrize("data, words", [
    ({"inner": {"name": "a", "sides": [1, 2]}, "rate": None, "counts": {}}, "'n' missing"),
    ({"n": True, "inner": {"name": "a", "sides": [1, 2]}, "rate": None, "counts": {}},
     "Outer.n: a boolean"),
    ({"n": 1, "inner": {"name": "a", "sides": [1, 2, 3]}, "rate": None, "counts": {}},
     "Outer.inner"),
    ({"n": "x", "inner": {"name": "a", "sides": [1, 2]}, "rate": None, "counts": {}},
     "Outer.n"),
])
def test_a_form_that_does_not_fit_is_one_value_error_naming_the_field(data, words):
    with pytest.raises(ValueError, match=words):
        from_plain(Outer, data)


def test_only_records_have_a_plain_form():
    with pytest.raises(TypeError, match="dataclass instance"):
        to_plain({"n": 1})


def test_the_summary_keeps_its_documented_key_order_and_reads_an_older_form():
    summary = Summary(n=4, n_passed=3, pass_rate=0.75, pass_rate_ci95=(0.3, 0.95),
                      count_exact_rate=1.0, count_mae=0.0, area_rel_err={"p50": 0.01},
                      area_rel_err_signed={"p50": -0.01}, marker_id_accuracy=None,
                      failures={"area_off": 1}, latency_ms={"p50": 10.0})
    d = summary.to_dict()
    assert list(d)[:4] == ["n", "n_passed", "pass_rate", "pass_rate_ci95"]
    assert list(d)[-3:] == ["robust_failure_rate", "phase_dependent_failure_rate", "phase_check"]
    assert Summary.from_dict(json.loads(json.dumps(d))) == summary
    older = {k: v for k, v in d.items() if k not in ("n_passed", "pass_rate_ci95")}
    back = Summary.from_dict(older)
    assert back.n_passed == 3 and back.pass_rate_ci95 == (0.0, 1.0)
