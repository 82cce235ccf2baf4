"""The fast ground-truth check (arenabench.schemas.quickcheck) says "valid" exactly when
jsonschema and the finite-number rule do: on real GT records and on thousands of mutations."""

import copy
import json
import math
import random

import jsonschema
import pytest

from arenabench import schemas
from arenabench.eval.datasets.bigset import template_records
from arenabench.schemas.quickcheck import all_finite, compile_check

#: Values put in place of a random leaf or member.
REPLACEMENTS = (-1, 0, 1, 2, 1.0, 1.5, -0.5, 255, 256, 2**70, math.nan, math.inf, -math.inf,
                True, False, None, "x", "inner", "nw", [], [1.0], [1.0, 2.0], [1.0, 2.0, 3.0],
                [[1.0, 2.0]], {}, {"a": 1}, 1e300, "arenabench.gt/1")


def _slow_valid(doc) -> bool:
    validator = schemas._gt_validator()
    return all_finite(doc) and not any(True for _ in validator.iter_errors(doc))


def _paths(obj, path=()):
    yield path
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, (*path, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, (*path, i))


def _mutate(doc, rng: random.Random):
    out = copy.deepcopy(doc)
    path = rng.choice(list(_paths(out))[1:])
    parent = out
    for p in path[:-1]:
        parent = parent[p]
    if isinstance(parent, dict) and rng.random() < 0.15:
        del parent[path[-1]]
    else:
        parent[path[-1]] = copy.deepcopy(rng.choice(REPLACEMENTS))
    return out


@pytest.fixture(scope="module")
def records():
    return template_records(4)


def test_real_records_pass(records):
    quick = schemas._quick_gt_check()
    assert quick is not None
    for record in records:
        assert quick(record) and _slow_valid(record)
        assert schemas.gt_problem(record) is None


@pytest.mark.integration
def test_mutations_agree_with_jsonschema(records):
    quick = schemas._quick_gt_check()
    rng = random.Random(0)
    invalid = 0
    for i in range(800):
        doc = _mutate(records[i % len(records)], rng)
        expected = _slow_valid(doc)
        assert quick(doc) == expected, json.dumps(doc, default=str)[:300]
        invalid += not expected
        if not expected:  # the message still comes from jsonschema
            assert schemas.gt_problem(doc) is not None
    assert 80 < invalid < 780  # the mutations hit both sides


def test_unsupported_keyword_is_not_compiled():
    assert compile_check({"type": "object", "patternProperties": {}}) is None
    assert compile_check({"type": "string", "format": "date"}) is None
    assert compile_check({"type": "integer", "minimum": 0})(3) is True
    assert compile_check({"type": "integer", "minimum": 0})(-3) is False
    assert compile_check({"type": "integer"})(3.0) is True  # as jsonschema
    assert compile_check({"type": "number"})(True) is False


def test_schema_sanity():
    jsonschema.validators.validator_for(schemas.gt_schema()).check_schema(schemas.gt_schema())


def test_the_schema_bounds_are_the_declared_limits():
    """The shipped schema states the limits of ``arenabench.limits`` (a JSON file cannot
    import them): the numbers reports bin or plot are bounded by what a scene or frame holds."""
    from arenabench import limits

    s = schemas.gt_schema()
    props = s["properties"]
    assert props["count"]["maximum"] == props["components"]["maximum"] == limits.MAX_COUNT
    assert limits.MAX_COUNT == limits.MAX_SCENE_OBJECTS
    assert s["$defs"]["area"]["maximum"] == limits.MAX_AREA_PX
    assert s["$defs"]["size"]["items"]["maximum"] == limits.MAX_IMAGE_SIDE_PX
    assert props["markers"]["items"]["properties"]["id"]["maximum"] == limits.MAX_MARKER_ID
    assert props["obstacles"]["maxItems"] == limits.MAX_SCENE_OBJECTS


def test_max_marker_id_is_the_last_id_of_the_largest_predefined_dictionary():
    import cv2

    from arenabench.limits import MAX_MARKER_ID

    sizes = [cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name)).bytesList.shape[0]
             for name in dir(cv2.aruco) if name.startswith("DICT_")]
    assert max(sizes) - 1 == MAX_MARKER_ID
