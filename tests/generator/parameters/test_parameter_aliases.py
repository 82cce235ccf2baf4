"""Short parameter names (as the sweep docs write them) resolve to the canonical ones."""

import pytest

from arenabench.eval.sweep.grid import parse_vary
from arenabench.generator.parameters.param_values import ALIASES, parse_override
from arenabench.generator.parameters.params import PARAMETERS, Range


def test_every_alias_points_at_a_real_parameter():
    assert ALIASES
    assert all(target in PARAMETERS for target in ALIASES.values())
    assert not set(ALIASES) & set(PARAMETERS)


def test_set_and_vary_accept_the_alias_and_record_the_canonical_name():
    assert parse_override("noise.sigma=0:5") == ("degrade.noise_sigma", Range(0.0, 5.0))
    axis = parse_vary("noise.sigma=0,5,10")
    assert axis.key == "degrade.noise_sigma"
    assert list(axis.values) == [0.0, 5.0, 10.0]


def test_alias_values_are_still_validated():
    with pytest.raises(ValueError, match=r"degrade\.jpeg_quality"):
        parse_override("jpeg.quality=abc")
