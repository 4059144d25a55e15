"""Property tests: every codec, driver call and emulator parser on arbitrary and mutated bytes (issue 17 item 7).

Each target (``tests/fakes/fuzz_targets.py``) either accepts an input or rejects it with its own clean error; any
other exception, or an emulator reply outside its protocol, fails the test.  Counts are modest here;
``benchmarks/fuzz.py`` runs the same targets on ~100,000 inputs.
"""
from __future__ import annotations

import random

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from tests.fakes.fuzz_targets import TARGETS, generate, outcome


@pytest.mark.parametrize("name", sorted(TARGETS))
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.one_of(st.binary(max_size=200), st.randoms(use_true_random=False).map(lambda r: r.random())))
def test_target_never_crashes(name, data):
    target = TARGETS[name]
    if isinstance(data, float):                     # a seeded mutation of one of the target's valid inputs
        data = generate(random.Random(data), target)
    assert outcome(target, data) in ("accepted", "rejected")


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_seeds_are_accepted(name):
    """The valid inputs the mutations start from are accepted: the targets test something."""
    target = TARGETS[name]
    results = [outcome(target, s) for s in target.seeds]
    assert results.count("accepted") >= len(results) - 1, results
