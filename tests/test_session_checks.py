"""Acceptance checks on the emulated twin: a clean run passes them, a gross sighting error fails the miss distance.

The miss-distance limit only becomes sharp once the runner has refitted the stations from the ruler steps, so every
session here starts with the ruler; the gross error is injected later, through the world's fault hook or the
scenario's gross-error rate.
"""
from __future__ import annotations

import sqlite3

import numpy as np
import pytest

from acq.session.checks import DEFAULT_LIMITS
from app.demo import build_demo, demo_plan
from sim.twin import Twin
from calib.units import ARCSEC

SEED = 4


@pytest.fixture(scope="module")
def poses_deg():
    return demo_plan(Twin(seed=SEED), SEED, n_poses=8)["poses"]


def _plan(poses):
    return {"procedures": ["ruler", "sweeps", "poses", "transmission", "compliance", "coupling"],
            "ruler": {"repeats": 2}, "sweeps": {"points": 3, "span_deg": 40.0, "joints": [1, 3, 5]},
            "poses": poses, "transmission": {"joints": [4], "points": 5, "range_deg": {"4": [-100.0, 100.0]}},
            "compliance": {"joints": [3]}, "coupling": {"pairs": [[5, 6]]}, "seed": SEED}


def _checks(db):
    with sqlite3.connect(db) as c:
        return c.execute("SELECT s.key, r.attempt, r.name, r.passed, r.value, r.limit_value FROM check_result r "
                         "JOIN step s USING (step_id)").fetchall()


def test_clean_run_passes_its_checks_with_sharp_miss_limits(tmp_path, poses_deg):
    d = build_demo(tmp_path / "c.db", seed=SEED, plan=_plan(poses_deg))
    logs = []
    d.runner.subscribe(lambda ev: logs.append(ev.data["text"]) if ev.kind == "log" else None)
    try:
        assert d.runner.run() == "finished"
        assert d.runner.stations_fitted
    finally:
        d.close()
    rows = _checks(tmp_path / "c.db")
    failed = [r for r in rows if not r[3]]
    assert len(rows) > 200 and len(failed) <= 1, failed          # "almost": one 6-sigma-ish fluke tolerated
    miss = [r for r in rows if r[2].startswith("miss distance") and not r[0].startswith("ruler/")]
    # after the ruler the limit is noise-based (sub-mm), not the coarse 5 mm of the set-up stations
    assert miss and max(r[5] for r in miss) < 1.0 and min(r[5] for r in miss) >= DEFAULT_LIMITS["miss_distance_floor_mm"]
    assert any("stations refitted" in t for t in logs)
    plaus = [r for r in rows if r[2].startswith("plausible")]
    assert plaus and all(r[4] <= r[5] for r in plaus) and max(r[5] for r in plaus) < 150.0


def test_injected_sighting_error_fails_the_miss_distance_and_is_repeated(tmp_path, poses_deg):
    plan = dict(_plan(poses_deg), procedures=["ruler", "poses"])
    d = build_demo(tmp_path / "g.db", seed=SEED, plan=plan)
    target = "poses/003"

    def inject(ev):
        if ev.kind == "step_started" and ev.data["key"] == target and ev.data["attempt"] == 1:
            # theodolite A sighted 40" above the target centre, in both faces of this step
            d.world.inject_sighting_error("A", v_rad=-40 * ARCSEC, readings=2)

    d.runner.subscribe(inject)
    try:
        assert d.runner.run() == "finished"
    finally:
        d.close()
    rows = _checks(tmp_path / "g.db")
    first = [r for r in rows if r[0] == target and r[1] == 1 and r[2] == "miss distance P"]
    second = [r for r in rows if r[0] == target and r[1] == 2 and r[2] == "miss distance P"]
    assert first and not first[0][3], first
    # 40" at ~3 m is ~0.6 mm: the coarse set-up limit (5 mm) would have let it through
    assert first[0][4] < DEFAULT_LIMITS["miss_distance_mm"]
    assert second and second[0][3], second                     # the scripted operator repeated; clean the 2nd time
    others = [r for r in rows if r[2].startswith("miss distance") and r[0] != target]
    assert all(r[3] for r in others)


def test_scenario_gross_errors_fail_miss_distances(tmp_path, poses_deg):
    plan = dict(_plan(poses_deg), procedures=["ruler", "poses"])
    d = build_demo(tmp_path / "r.db", seed=SEED, plan=plan, script={"policy": "accept"})

    def switch_on(ev):                  # after the ruler: gross errors of 60" in a third of the readings
        if ev.kind == "step_started" and ev.data["key"] == "poses/000":
            d.world.twin.scenario.gross_rate = 0.35

    d.runner.subscribe(switch_on)
    try:
        assert d.runner.run() == "finished"
    finally:
        d.close()
        d.world.twin.scenario.gross_rate = 0.0
    rows = [r for r in _checks(tmp_path / "r.db") if r[0].startswith("poses/") and r[2].startswith("miss")]
    assert np.sum([not r[3] for r in rows]) >= 2, rows


def test_fault_hook_rejects_bad_input(tmp_path):
    from calib.errors import RobocalError
    from sim.emulate.twin_world import TwinWorld
    w = TwinWorld(Twin(seed=0))
    with pytest.raises(RobocalError):
        w.inject_sighting_error("C", v_rad=1e-4)
    with pytest.raises(RobocalError):
        w.inject_sighting_error("A", v_rad=float("nan"))
