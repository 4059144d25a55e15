"""Property tests: every file reader on arbitrary and damaged files (issue 17 item 7).

Each reader (``tests/fakes/fuzz_file_targets.py``: robot and scenario TOML, model and set-up JSON, pose and
readings CSV, session database) either reads a file or rejects it with one :class:`RobocalError` line; any other
exception fails the test.  Counts are modest here; ``benchmarks/fuzz_files.py`` runs ~50,000 inputs.
"""
from __future__ import annotations

import random

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from tests.fakes.fuzz_file_targets import generate_file, targets
from tests.fakes.fuzz_targets import outcome

NAMES = ["robot TOML", "scenario TOML", "model JSON", "set-up JSON", "pose CSV", "readings CSV", "session database"]


pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.one_of(st.binary(max_size=300), st.randoms(use_true_random=False).map(lambda r: r.random())))
def test_reader_never_crashes(name, data):
    target = targets()[name]
    if isinstance(data, float):                     # a seeded mutation or structured damage of a valid file
        data = generate_file(random.Random(data), target)
    assert outcome(target, data) in ("accepted", "rejected")


@pytest.mark.parametrize("name", NAMES)
def test_valid_files_are_read(name):
    """The files the damage starts from are read: the targets test something."""
    target = targets()[name]
    assert all(outcome(target, s) == "accepted" for s in target.seeds)


@settings(max_examples=80, deadline=None)
@given(text=st.text(max_size=200))
def test_any_text_as_robot_toml_is_read_or_one_line(text):
    from calib.errors import RobocalError
    from calib.robot import parse_robot
    try:
        parse_robot(text, "fuzz.toml")
    except RobocalError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("fuzz.toml")
