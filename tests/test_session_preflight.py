"""Pre-flight of session plans: what a real cell cannot do is refused before the robot moves, one line per step.

Truths used here come from the geometry the test builds, not from the code under test: a weight on a level 500 mm
lever turns its joint by m g 0.5 N m; an axis standing vertical is turned by nothing; the description's joint limits;
a point placed on the ray from a station through the robot's arm is hidden by the arm.
"""
from __future__ import annotations

import json
import sqlite3
import subprocess
import sys

import numpy as np
import pytest

from app.demo import build_demo, demo_plan, demo_setup
from acq.session.preflight import Preflight, failing_lines, load_torques_nm
from acq.session.procedures import all_steps
from calib.profile import THESIS_READY_DEG as READY_DEG
from acq.session.setup import session_setup
from acq.session.steps import Step, TargetSpec
from calib.loading import load_robot
from sim.twin import Twin, load_scenario
from calib.units import DEG

G = 9.80665


@pytest.fixture(scope="module")
def twin():
    return Twin(load_scenario(), seed=0)


@pytest.fixture(scope="module")
def setup(twin):
    return session_setup(demo_setup(twin), twin.robot)


def _pf(twin, setup, **limits):
    return Preflight(twin.robot, setup, limits=limits or None)


def test_default_plans_pass(twin, setup):
    from app.commands.session import default_plan
    for plan in (demo_plan(twin, 0), default_plan()):
        steps = all_steps(plan, setup)
        assert failing_lines(_pf(twin, setup).check(steps)) == []


def test_te_beyond_joint_limit_is_one_line_per_step(twin, setup):
    plan = demo_plan(twin, 0)
    plan["procedures"] = ["transmission"]
    plan["transmission"]["range_deg"] = {"4": [-150.0, 150.0], "6": [-150.0, 150.0]}
    lines = failing_lines(_pf(twin, setup).check(all_steps(plan, setup)))
    lo = twin.robot.limits_rad[3, 0] / DEG                  # -110 in the description
    beyond = [a for a in np.linspace(-150, 150, 25) if a < lo + 2.0]
    assert len(lines) == len(beyond) == 4
    assert lines[0].startswith("te/j4/00: joint limit: joint 4 at -150.0 deg, limit -108.0 deg")


def _load_step(setup, joint, pose, lever_mm=500.0, kg=2.0, theta_deg=0.0):
    from acq.session.setup import session_setup as ss
    s = {**setup, "compliance": {str(joint): {"lever_mm": lever_mm, "loads_n": [kg * G], "theta_i_deg": theta_deg,
                                              "pose_deg": list(pose)}}}
    s = ss(s, load_robot())
    return next(iter(all_steps({"procedures": ["compliance"], "compliance": {"joints": [joint]}}, s))), s


def test_load_torque_from_geometry(twin, setup):
    # joint 4 with the forearm level: a 2 kg weight on a level 500 mm lever turns it by m g r exactly
    step, s = _load_step(setup, 4, (0.0, -90.0, 0.0, 0.0, 0.0, 0.0))
    pf = Preflight(twin.robot, s)
    geo = pf.geometry(step)
    tau = load_torques_nm(pf, geo.fp, np.asarray(step.pose_deg) * DEG, step.setup["loads"])
    assert abs(abs(tau[3]) - 2.0 * G * 0.5) < 1e-4          # the point is stored to 1 um
    assert np.all(tau[4:] == 0.0)                           # joints beyond link 4 do not carry it
    assert pf.check_step(step) == []
    # raised 70 deg, the lever gives cos 70 = 34 % of it: below the 50 % limit
    step, s = _load_step(setup, 4, (0.0, -90.0, 0.0, 0.0, 0.0, 0.0), theta_deg=70.0)
    pf = Preflight(twin.robot, s)
    tau = load_torques_nm(pf, pf.geometry(step).fp, np.asarray(step.pose_deg) * DEG, step.setup["loads"])
    assert abs(abs(tau[3]) - 2.0 * G * 0.5 * np.cos(np.radians(70.0))) < 1e-4
    assert [f.check for f in pf.check_step(step)] == ["load torque"]


def test_load_on_vertical_axis_is_refused(twin, setup):
    step, s = _load_step(setup, 4, READY_DEG)
    found = Preflight(twin.robot, s).check_step(step)
    assert [f.check for f in found] == ["load torque"]
    assert found[0].value < 1e-9 and found[0].limit > 1.0
    assert found[0].line().startswith(f"{step.key}: load torque: 2.00 kg hung there gives 0.00 N m about joint 4")


def test_sweep_radius_limits(twin, setup):
    plan = {"procedures": ["sweeps"], "sweeps": {"points": 3, "joints": [1, 4, 6]}}
    for r, ok in ((50.0, False), (600.0, True), (1300.0, False)):
        s = session_setup({k: v for k, v in setup.items() if k != "sweep_targets"} | {"sweep_radius_mm": r},
                          twin.robot)
        found = _pf(twin, s).check(all_steps(plan, s))
        radius = [f for f in found if f.check == "sweep radius"]
        assert (not radius) == ok, (r, failing_lines(found))
        for f in radius:
            assert abs(f.value - r) < 1.0


def test_the_old_flange_target_turns_on_50_mm(twin, setup):
    s = {k: v for k, v in setup.items() if k != "sweep_targets"}
    s["sweep_targets"] = {}
    plan = {"procedures": ["sweeps"], "sweeps": {"points": 2, "joints": [4, 6]}}
    found = _pf(twin, s).check(all_steps(plan, s))
    assert {f.key for f in found} == {"sweep/j4/00", "sweep/j4/01", "sweep/j6/00", "sweep/j6/01"}
    assert all(abs(f.value - 50.0) < 1.0 for f in found)     # hypot(50, 0): the tool target's offset


def _point_step(key, p, pose=None):
    return Step(key, "ruler", key, "", pose_deg=pose, targets=(TargetSpec("X", point_mm=tuple(p)),))


def test_sight_checks(twin, setup):
    pf = _pf(twin, setup)
    L = setup["stations"]["L_mm"]
    cases = {
        "close": ([300.0, 400.0, 0.0], "closer than its focus distance"),
        "steep": ([L / 2, 1500.0, 2500.0], "elevation"),
        "far": ([L / 2, 20000.0, 0.0], "beyond"),
        "flat": ([-3000.0, 300.0, 0.0], "sight lines meet at"),
        "good": ([L / 2, 2500.0, 300.0], None),
    }
    for key, (p, text) in cases.items():
        found = pf.check_step(_point_step(key, p))
        if text is None:
            assert found == []
        else:
            assert any(text in f.detail for f in found), (key, [f.line() for f in found])


def test_robot_in_the_line_of_sight(twin, setup):
    """A point on the ray from station A through the middle of the upper arm, beyond the robot, is hidden."""
    pf = _pf(twin, setup, link_radius_mm=80.0)
    geo = pf.geometry(Step("x", "poses", "", "", pose_deg=READY_DEG))
    mid = 0.5 * (geo.fp.frame_t[0, 1] + geo.fp.frame_t[0, 2])   # shoulder to elbow (frame origins)
    a = pf.stations["A"].position
    hidden = mid + 600.0 * (mid - a) / np.linalg.norm(mid - a)
    found = pf.check_step(_point_step("behind", hidden, READY_DEG))
    assert any("hides it" in f.detail and "station A" in f.detail for f in found), [f.line() for f in found]
    # without link geometry (the description has none, and this set-up gives no link radius) it does not apply
    bare = {k: v for k, v in setup.items() if k != "preflight"}
    assert not any("hides it" in f.detail for f in _pf(twin, bare).check_step(_point_step("b", hidden, READY_DEG)))


def _bad_plan(twin):
    plan = demo_plan(twin, 3)
    plan["procedures"] = ["coupling", "transmission"]
    plan["transmission"] = {"joints": [4], "points": 3, "range_deg": {"4": [-150.0, 0.0]}}
    return plan


def test_runner_refuses_and_touches_nothing(tmp_path, twin):
    db = tmp_path / "s.db"
    d = build_demo(db, seed=3, plan=_bad_plan(twin))
    try:
        events = []
        d.runner.subscribe(events.append)
        assert d.runner.run() == "refused"
    finally:
        d.close()
    pre = [e for e in events if e.kind == "preflight"]
    assert len(pre) == 1 and pre[0].data["lines"] == ["te/j4/00: joint limit: joint 4 at -150.0 deg, limit -108.0 "
                                                      "deg (-110.0 with a 2 deg margin)"]
    c = sqlite3.connect(db)
    try:
        assert c.execute("SELECT count(*) FROM step").fetchone()[0] == 0
        assert c.execute("SELECT exit_status FROM session").fetchone()[0] is None
    finally:
        c.close()


def test_resumed_session_keeps_its_steps(tmp_path, twin):
    """A session recorded in part, then found to fail (its plan edited): the refusal changes nothing stored."""
    db = tmp_path / "r.db"
    plan = _bad_plan(twin)
    plan["procedures"] = ["coupling"]
    d = build_demo(db, seed=3, plan=plan, operator=None)
    try:
        assert d.runner.run() == "finished"
    finally:
        d.close()
    c = sqlite3.connect(db)
    before = c.execute("SELECT * FROM step ORDER BY step_id").fetchall(), c.execute("SELECT * FROM session").fetchall()
    c.execute("UPDATE session SET plan_json=?", (json.dumps(_bad_plan(twin)),))
    c.commit()
    c.close()
    d = build_demo(db, resume=True)
    try:
        assert d.runner.run() == "refused"
    finally:
        d.close()
    c = sqlite3.connect(db)
    after = c.execute("SELECT * FROM step ORDER BY step_id").fetchall(), c.execute("SELECT * FROM session").fetchall()
    c.close()
    assert after[0] == before[0]
    assert [r[:9] + r[10:] for r in after[1]] == [r[:9] + r[10:] for r in before[1]]   # only plan_json differs


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=120)


def test_plan_check_cli(tmp_path, twin, setup):
    good = tmp_path / "good.json"
    good.write_text(json.dumps(demo_setup(twin)))
    r = _cli("plan", "check", str(good))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "all pass the pre-flight" in r.stdout
    bad = demo_setup(twin)
    bad["compliance"]["4"]["pose_deg"] = list(READY_DEG)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(bad))
    r = _cli("plan", "check", str(path))
    assert r.returncode == 2
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("compliance/")]
    # one line per loaded step (loading, then unloading in reverse): the first and last hang no weight
    loads = bad["compliance"]["4"]["loads_n"]
    assert len(lines) == sum(v > 0 for v in loads + loads[-2::-1]) and all("load torque" in ln for ln in lines)
    assert "Traceback" not in r.stderr


def test_a_ruler_mark_the_ruler_lacks_is_one_line(tmp_path, twin):
    bad = demo_setup(twin)
    bad["ruler"]["placements"][0]["marks"] = ["C", "Q"]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(bad))
    r = _cli("plan", "check", str(path))
    assert r.returncode == 2 and "Traceback" not in r.stderr and "internal error" not in r.stderr, r.stderr
    assert "ruler.placements[0].marks: unknown mark 'Q'" in r.stderr, r.stderr


def test_a_point_p_on_a_link_the_robot_lacks_is_one_line(tmp_path, twin):
    bad = demo_setup(twin)
    bad["point_p"] = {"link": 9, "L_p_mm": 100.0}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(bad))
    r = _cli("plan", "check", str(path))
    assert r.returncode == 2 and "Traceback" not in r.stderr and "internal error" not in r.stderr, r.stderr
    assert "point_p: link must be one of the robot's links 1..6, got 9" in r.stderr, r.stderr


def test_plan_setup_writes_the_session_setup(tmp_path):
    """``plan setup te --out`` writes the designed extended tool into the set-up; the file passes the pre-flight and
    keeps the rest of the set-up it started from."""
    base = tmp_path / "base.json"
    r = _cli("session", "--write-setup", str(base))
    assert r.returncode == 0, r.stderr
    out = tmp_path / "designed.json"
    r = _cli("plan", "setup", "te", "--setup", str(base), "--out", str(out), "--json")
    assert r.returncode == 0, r.stderr
    design = json.loads(r.stdout)
    doc = json.loads(out.read_text())
    a1, a2 = np.array(doc["extended_tool"]["A1_mm"]), np.array(doc["extended_tool"]["A2_mm"])
    assert abs(np.linalg.norm(a2 - a1) - design["variables"]["Rd_mm"]) < 0.2
    assert doc["ruler"] == json.loads(base.read_text())["ruler"]
    r = _cli("plan", "check", str(out))
    assert r.returncode == 0, r.stdout


@pytest.mark.parametrize("edit, text", [
    (lambda s: s["compliance"]["4"].pop("point_mm"), "set-up: compliance.4: missing lever_mm"),
    (lambda s: s["compliance"]["4"].update(pose_deg=[0, 0]), "set-up: compliance.4: pose_deg needs 6"),
    (lambda s: s["compliance"].update({"9": s["compliance"]["3"]}), "set-up: compliance.9: joint 9 is not one of"),
    (lambda s: s["link"].update(loads_n=[0, -5]), "link.loads_n[1]: -5 is less than the minimum of 0"),   # schema
    (lambda s: s["link"].pop("gauges_x_mm"), "set-up: link: missing gauges_x_mm"),
])
def test_malformed_setup_is_one_line(tmp_path, edit, text):
    from acq.session.setup import standard_setup
    s = standard_setup()
    edit(s)
    path = tmp_path / "s.json"
    path.write_text(json.dumps(s))
    r = _cli("plan", "check", str(path))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines() == [f"robocal: error: {r.stderr.split('error: ', 1)[1].strip()}"]
    assert text in r.stderr, r.stderr


def test_a_step_checked_again_sees_the_stations_moved(twin, setup):
    """The runner checks a step before the session and again with the refitted stations: the findings that read
    the stations follow them (kept per step are only the others, e.g. a joint beyond its limit)."""
    from dataclasses import replace
    pf = _pf(twin, setup)
    lo = twin.robot.limits_rad[3, 0] / DEG
    pose = tuple(READY_DEG[:3]) + (lo - 5.0,) + tuple(READY_DEG[4:])
    a = pf.stations["A"].position
    step = _point_step("p", a + np.array([0.0, 2000.0, 100.0]), pose)
    first = [f.check for f in pf.check_step(step)]
    assert first == ["joint limit"]
    pf.stations = {**pf.stations, "A": replace(pf.stations["A"], y_mm=float(a[1]) + 1900.0)}   # 100 mm away now
    again = pf.check_step(step)
    assert [f.check for f in again] == ["joint limit", "sight"]
    assert "closer than its focus distance" in again[1].detail


def test_segment_distance_against_a_dense_grid():
    """The exact segment-to-segment distance that screens the line of sight: never above the closest pair of a
    dense grid of points on both segments, and within the grid's spacing of it (parallel, crossing, skew and
    point-like segments)."""
    from acq.session.preflight import _segment_distance
    rng = np.random.default_rng(7)
    cases = [([0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]),           # parallel, 1 apart
             ([0, 0, 0], [1, 0, 0], [0.5, -1, 0.2], [0.5, 1, 0.2]),   # crossing 0.2 above
             ([0, 0, 0], [0, 0, 0], [1, 1, 1], [2, 2, 2]),             # a point and a segment
             ([3, 3, 3], [3, 3, 3], [0, 0, 0], [0, 0, 0])]             # two points
    cases += [tuple(rng.normal(size=(4, 3)) * 100) for _ in range(30)]
    s = np.linspace(0.0, 1.0, 401)
    for p1, q1, p2, q2 in cases:
        p1, q1, p2, q2 = (np.asarray(v, float) for v in (p1, q1, p2, q2))
        a, b = p1 + s[:, None] * (q1 - p1), p2 + s[:, None] * (q2 - p2)
        grid = np.sqrt(((a[:, None] - b[None]) ** 2).sum(-1)).min()
        exact = _segment_distance(p1.tolist(), q1.tolist(), p2.tolist(), q2.tolist())
        step = (np.linalg.norm(q1 - p1) + np.linalg.norm(q2 - p2)) / 400
        assert exact <= grid + 1e-9
        assert grid - exact <= step + 1e-9


def test_screened_sight_checks_equal_the_unscreened_ones(twin, setup, monkeypatch):
    """The plain-float screens of the line of sight and of the intersection angle only skip work: over points
    around the arm (some hidden behind its links, some at the angle limits) the findings are those of the checks
    computed in full."""
    import acq.session.preflight as pre
    pf = _pf(twin, setup, link_radius_mm=80.0, intersection_deg=[60.0, 100.0])
    geo = pf.geometry(Step("x", "poses", "", "", pose_deg=READY_DEG))
    org = geo.fp.frame_t[0]
    a = pf.stations["A"].position
    rng = np.random.default_rng(3)
    points = []
    for k in range(1, len(org)):                       # behind each link as seen from A, near and far off the line
        mid = 0.5 * (org[k - 1] + org[k])
        for off in (0.0, 60.0, 79.0, 81.0, 150.0):
            side = rng.normal(size=3)
            side -= (side @ (mid - a)) * (mid - a) / np.linalg.norm(mid - a) ** 2
            points.append(mid + 600.0 * (mid - a) / np.linalg.norm(mid - a) + off * side / np.linalg.norm(side))
    points += list(np.array([setup["stations"]["L_mm"] / 2, 2500.0, 300.0]) + rng.normal(size=(40, 3)) * 1500.0)
    steps = [_point_step(f"p{i}", p, READY_DEG) for i, p in enumerate(points)]
    screened = [f.line() for s in steps for f in pf.check_step(s)]
    assert any("hides it" in ln for ln in screened) and any("sight lines meet at" in ln for ln in screened)
    monkeypatch.setattr(pre, "_clear_of", lambda *a: False)
    monkeypatch.setattr(pre, "_angle_deg", lambda *a: float("nan"))
    full = [f.line() for s in steps for f in _pf(twin, setup, link_radius_mm=80.0,
                                                 intersection_deg=[60.0, 100.0]).check_step(s)]
    assert screened == full


def test_the_arm_alone_is_kept_per_pose(twin, setup):
    """The arm's own torques (subtracted from the loaded ones) are kept per pose: one pre-flight checking steps at
    two poses gives each the torques a fresh one gives (a kept value that ignored the pose would leave the arm's
    weight in the second: newtons-metres on joints 2 and 3)."""
    pf = None
    for pose in ((0.0, -90.0, 0.0, 0.0, 0.0, 0.0), (0.0, -45.0, 30.0, 0.0, 0.0, 0.0)):
        step, s = _load_step(setup, 4, pose)
        pf = pf or Preflight(twin.robot, s)
        fresh = Preflight(twin.robot, s)
        q = np.asarray(step.pose_deg) * DEG
        kept = load_torques_nm(pf, pf.geometry(step).fp, q, step.setup["loads"])
        assert np.array_equal(kept, load_torques_nm(fresh, fresh.geometry(step).fp, q, step.setup["loads"]))
