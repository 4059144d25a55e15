"""The demo maps its set-up's old keys once (app.demo.build_demo): mapping a mapped set-up again changes nothing, for
the thesis Puma's bench, another robot's and a user's set-up file, so the set-up stored and the one the steps use
are the same document."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from acq.session.setup import session_setup, standard_setup
from acq.session.setup_types import setup_of
from app.demo import demo_setup, robot_twin
from sim.twin import Twin

ROOT = Path(__file__).resolve().parents[1]


def _benches():
    twin = Twin(seed=0)
    yield "puma", twin, demo_setup(twin), True
    yield "puma, a user's file", twin, demo_setup(twin, standard_setup()), False
    other, _, base = robot_twin(ROOT / "calib" / "data" / "tiago_arm.toml", 0)
    yield "tiago arm", other, demo_setup(other, base), True


@pytest.mark.parametrize("name,twin,bench,own", list(_benches()), ids=lambda v: v if isinstance(v, str) else "")
def test_mapping_a_mapped_set_up_changes_nothing(name, twin, bench, own):
    once = session_setup(bench, twin.robot, own=own)
    twice = session_setup(once, twin.robot)
    assert json.dumps(twice, sort_keys=True) == json.dumps(once, sort_keys=True)
    assert setup_of(twice) == setup_of(once)
