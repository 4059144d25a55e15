"""Transmission error of joints 2 and 3 as options (``--te-joints``): the plan key, the pre-flight of their runs, and
a demo restricted to the ruler, the sweeps and joint 3's run reporting joint 3.  The default twin has no
transmission error on joint 3, but it has joint compliance: turning joint 3 turns the forearm's weight about it, so
the measured angle lags the encoder by the gravity deflection, once per turn (about m g r / K3 = 0.04 deg).  The
run must report that as a first-order periodic error of that amplitude."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.demo import build_demo, transmission_plan
from app.reprocess import reprocess


def test_the_option_maps_to_the_plan_key():
    from app.commands.session import default_plan
    assert default_plan()["transmission"]["joints"] == [4, 6]                 # default unchanged
    plan = default_plan(te_joints=[2, 3, 4, 6])["transmission"]
    assert plan["joints"] == [2, 3, 4, 6] and set(plan["range_deg"]) == {"2", "3", "4", "6"}
    assert transmission_plan([3])["range_deg"] == {"3": [-90.0, 90.0]}


@pytest.mark.parametrize("bad", ["5", "2,2", "x", "", "7"])
def test_bad_te_joints_is_one_line(bad, capsys):
    assert main(["demo", "--te-joints", bad]) == 2
    err = capsys.readouterr().err
    assert "--te-joints" in err and "Traceback" not in err


def test_joint_2_and_3_runs_pass_the_preflight_and_a_limit_is_caught():
    from acq.session.preflight import Preflight
    from acq.session.procedures import transmission
    from acq.session.setup import session_setup, standard_setup
    from acq.session.setup_types import setup_of
    from calib.loading import load_robot
    robot = load_robot(None)
    setup = setup_of(session_setup(standard_setup(), robot))
    pf = Preflight(robot, setup)
    steps = list(transmission({"transmission": transmission_plan([2, 3])}, setup))
    assert {s.meta["joint"] for s in steps} == {2, 3}
    assert pf.check(steps) == []
    wide = transmission_plan([3])
    wide["range_deg"]["3"] = [-90.0, 150.0]                 # joint 3 to 240 deg: beyond its 225 deg limit
    lines = [f.line() for f in pf.check(list(transmission({"transmission": wide}, setup)))]
    assert lines and all("joint limit" in ln and ln.startswith("te/j3/") for ln in lines)


def test_demo_of_joint_3_reports_its_gravity_deflection(tmp_path):
    """Joint 3 turned through 180 deg swings the forearm's weight about it: the measured angle lags the encoder by
    T3(q3) / K3, once per turn.  Its amplitude, predicted independently -- the gravity torques of the description's
    masses by plain cross products (:mod:`tests.fakes.thesis_puma`), over the thesis's K3 (1.156e5 lb in/rad below
    its breakpoint, section 5.5.2) -- is what the run must report, order 1, within 3 of its stated errors."""
    from tests.fakes.thesis_puma import ThesisPuma
    plan = {"procedures": ["ruler", "sweeps", "transmission"], "ruler": {"repeats": 2},
            "sweeps": {"points": 5, "span_deg": 60.0}, "transmission": transmission_plan([3], points=13), "seed": 4}
    keep = ("ruler/", "sweep/", "te/j3/")
    d = build_demo(tmp_path / "te3.db", seed=4, plan=plan, steps_filter=lambda s: s.key.startswith(keep))
    assert d.runner.run() == "finished"
    d.close()
    res = reprocess(str(tmp_path / "te3.db"))
    assert not res["problem_details"] and not res["problems"], res["problems"]
    est = {e["name"]: e for e in res["estimates"]}
    arm = ThesisPuma.from_toml(Path(__file__).resolve().parents[1] / "calib" / "data" / "puma560.toml")
    q3 = np.radians(np.linspace(-90.0, 90.0, 13))
    torque = np.array([arm.gravity_torques(np.radians([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]) + [0, 0, a, 0, 0, 0])[2]
                       for a in q3])
    s, c, _ = np.linalg.lstsq(np.stack([np.sin(q3), np.cos(q3), np.ones_like(q3)], -1), torque, rcond=None)[0]
    k3 = 1.156e5 * 0.1129848                          # lb in/rad -> N m/rad
    assert np.hypot(s, c) < 11.3                      # below the thesis's breakpoint (100 lb in): one slope
    w, a = est["te.j3.omega"], est["te.j3.amplitude1_rad"]
    assert abs(w["value"] - 1.0) < 3 * w["error"], w
    assert abs(a["value"] - np.hypot(s, c) / k3) < 3 * a["error"] and a["error"] < 0.3 * a["value"], a
    assert "dh.j3.a_mm" in est and np.isfinite(est["dh.j3.a_mm"]["value"])


def test_te_joints_on_a_resumed_session_is_refused(tmp_path, capsys):
    db = tmp_path / "old.db"
    db.write_bytes(b"x")                                # an existing session: its plan is fixed
    assert main(["session", "--emulate", "--db", str(db), "--te-joints", "2,3"]) == 2
    err = capsys.readouterr().err
    assert "--te-joints" in err and "resumed" in err and "Traceback" not in err
