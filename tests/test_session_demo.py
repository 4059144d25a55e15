"""The demo session end to end: real drivers on twin-driven emulators, scripted operator, pause/resume, reprocess
against the twin's truth, import/export round trips and the CLI."""
from __future__ import annotations

import gc
import json
import sqlite3

import numpy as np
import pytest

from app.cli import main
from app.demo import build_demo
from app.reprocess import reprocess

SMALL = {
    "procedures": ["ruler", "sweeps", "poses", "transmission", "compliance", "link_compliance", "coupling"],
    "ruler": {"repeats": 2},
    "sweeps": {"points": 5, "span_deg": 60.0},
    "transmission": {"joints": [4], "points": 19, "repeats": 2, "range_deg": {"4": [-105.0, 165.0]}},
    "compliance": {"joints": [3, 4]},
    "coupling": {"pairs": [[5, 6]]},
    "seed": 3,
}


def _scenario_with_link_compliance(folder) -> str:
    """The default scenario with its link-compliance effect switched on, so the dial gauges have bending to read."""
    from importlib import resources
    text = (resources.files("calib") / "data" / "twin_default.toml").read_text(encoding="utf-8")
    block = text[text.index('type = "link_compliance"'):]
    block = block[:block.index("[[effect]]")]
    on = text.replace(block, block.replace("enabled = false", "enabled = true"))
    assert on != text
    path = folder / "link_on.toml"
    path.write_text(on, encoding="utf-8")
    return str(path)


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A demo session recorded in two runs: paused after 25 decisions, then resumed to the end."""
    from sim.twin import Twin
    from app.demo import demo_plan
    folder = tmp_path_factory.mktemp("demo")
    db = folder / "s.db"
    plan = dict(SMALL, poses=demo_plan(Twin(seed=3), 3, n_poses=16)["poses"])
    d = build_demo(db, seed=3, plan=plan, script={"pause_after": 25}, scenario=_scenario_with_link_compliance(folder))
    events = []
    d.runner.subscribe(events.append)
    assert d.runner.run() == "paused"
    d.close()
    with sqlite3.connect(db) as c:
        assert c.execute("SELECT exit_status FROM session").fetchone()[0] == "paused"
        n_first = c.execute("SELECT count(*) FROM step").fetchone()[0]
    assert n_first == 25 - sum(1 for e in events if e.kind == "step_started" and e.data["attempt"] > 1)
    d = build_demo(db, resume=True)
    ev2 = []
    d.runner.subscribe(ev2.append)
    assert d.runner.run() == "finished"
    d.close()
    assert sum(e.kind == "step_skipped_done" for e in ev2) == n_first
    return db, events + ev2


def test_every_procedure_recorded_with_raw_frames(session):
    db, events = session
    with sqlite3.connect(db) as c:
        procs = {p for (p,) in c.execute("SELECT DISTINCT procedure FROM step")}
        assert procs == {"ruler", "sweep", "poses", "transmission", "compliance", "link_compliance", "coupling"}
        raw = [r for (r,) in c.execute("SELECT raw FROM reading LIMIT 50")]
        assert all(r.startswith(b"%R1P,0,") for r in raw)           # GeoCOM replies, as on the wire
        assert c.execute("SELECT count(*) FROM encoder_chunk WHERE n_samples >= 5").fetchone()[0] > 50
        assert c.execute("SELECT count(*) FROM operator_input WHERE name LIKE 'gauge%'").fetchone()[0] == 12
        assert c.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        assert c.execute("SELECT exit_status FROM session").fetchone()[0] == "success"
    kinds = {e.kind for e in events}
    assert {"state", "step_started", "reading", "check", "step_saved", "encoders", "finished"} <= kinds


def test_reprocess_recovers_the_twin(session):
    db, _ = session
    res = reprocess(str(db))
    est = {e["name"]: e for e in res["estimates"]}
    assert not res["problems"], res["problems"]

    def within(name, k=4.0, rel=None):
        e = est[name]
        assert e["truth"] is not None, name
        tol = k * e["error"] if rel is None else rel * abs(e["truth"])
        assert abs(e["value"] - e["truth"]) <= tol, (name, e)

    for n in ("ruler.L_mm", "ruler.gamma1_rad", "ruler.gamma2_rad", "dh.j2.a_mm", "dh.j4.d_mm", "dh.j3.a_mm",
              "te.j4.amplitude1_rad", "coupling.sigma56"):
        within(n)
    # the thesis's reduction (compensation scheme, eqs 4.3.12-15) and d3 from point P and L_p
    for n in ("comp.a1_mm", "comp.a2_mm", "comp.d1_mm", "comp.d2_mm", "comp.d3_mm"):
        within(n, k=3.0)
    assert est["comp.d3_mm"]["error"] < 0.5, est["comp.d3_mm"]
    within("ident.j2.a_mm")                 # running errors are in the pose-set model now
    # the gauges read the bending of the scenario's link compliance, the stiffness comes from torques computed from
    # the geometry: both within 4 of their stated errors as every estimate here (one noise draw: an honest 1-sigma
    # is exceeded 3-fold in 0.3 % of values, and this session's K4 sits at 3.04; benchmarks/bench_demo_honesty.py
    # scores the ratios over seeded runs, tests/test_session_example.py holds the shipped demo to 3), and the errors
    # small enough to mean something
    for n in ("link.j2.EI_Nmm2", "compliance.j3.K1_Nm_per_rad", "compliance.j4.K1_Nm_per_rad"):
        within(n)
        assert est[n]["error"] < 0.3 * abs(est[n]["value"]), est[n]
    # these few loads cannot place a breakpoint (the twin's two slopes of joint 3 differ by 6 %): one slope over every
    # load, said on K1, and no K2 or breakpoint reported
    for j in (3, 4):
        assert est[f"compliance.j{j}.K1_Nm_per_rad"].get("single_slope"), est[f"compliance.j{j}.K1_Nm_per_rad"]
        assert f"compliance.j{j}.K2_Nm_per_rad" not in est and f"compliance.j{j}.breakpoint_Nm" not in est
    assert all({"name", "value", "error", "unit", "truth", "held"} <= set(e) for e in res["estimates"])
    # held parameters are flagged, carry no error and say why; estimated ones are not flagged
    held = [e for e in res["estimates"] if e["held"]]
    assert held and all(e["error"] == 0.0 and e["name"].startswith("ident.") and "held" in e["note"] for e in held)


def test_the_identified_robots_truths_are_the_twins_in_the_fits_gauge(session):
    """robot.parameters[].truth used to be the twin's raw values (base yaw 0 where the fit's gauge puts joint 1's
    zero offset into it, j3.d 0 where it takes d2's error): now each estimated parameter's truth is the one its
    ident.* estimate is compared with, a held parameter has none, and the z-scores are those of honest errors."""
    db, _ = session
    res = reprocess(str(db))
    est = {e["name"]: e for e in res["estimates"]}
    z = []
    for p in res["robot"]["parameters"]:
        if not p["estimated"]:
            assert p["truth"] is None and "held" in p["note"], p
            continue
        e = est[f"ident.{p['name']}"]
        assert p["truth"] == e["truth"], (p, e)
        if p["truth"] is not None:
            z.append(abs(p["value"] - p["truth"]) / p["error"])
        else:
            assert "truth_raw" in p or p["name"].startswith("cross_coupling"), p
    assert len(z) >= 20 and np.median(z) < 1.5 and max(z) < 6.0, sorted(z)
    # what makes them a gauge, on the independent chain: the truths with the held values give the twin's own points
    from offline.reduction.session import load_session
    from sim.emulate.truth import session_twin
    from tests.test_truth_gauge import _points
    twin = session_twin(load_session(str(db)))
    geo = {p["name"]: p["truth"] if p["estimated"] else p["value"] for p in res["robot"]["parameters"]
           if p["name"].startswith(("base.", "tool.", "j"))}
    q = twin.random_poses(30)
    assert np.abs(_points(geo, q) - _points(twin.true_parameters(), q)).max() < 2e-4


def test_the_geometric_truths_are_the_oracles(session):
    """The truths beside the misalignment table and the compensation scheme are the thesis's formulas written out
    by the oracle (tests/fakes/oracle/scheme.py) on the twin's true parameters through the independent chain --
    not calib.estimators on exact data -- and the estimates land on them within 3 of their errors; the twin's own
    link value rides along as truth_raw where the scheme reads it otherwise (d1: the tilts between the axes)."""
    from offline.reduction.run import reduce_session
    from offline.reduction.session import load_session
    from sim.emulate.truth import score, session_twin
    from tests.test_truth_scheme import session_truths
    db, _ = session
    data = load_session(str(db))
    res = score(reduce_session(data), data)
    want = session_truths(session_twin(data), data.setup, res["trace"]["sweeps"]["q0_rad"])
    est = {e["name"]: e for e in res["estimates"] if e["name"].startswith(("comp.", "misalign."))}
    assert len(est) > 20 and {f"comp.{k}" for k in ("a1_mm", "a2_mm", "d1_mm", "d2_mm", "d3_mm")} <= set(est)
    for name, e in est.items():
        assert e["truth"] == pytest.approx(want[name], abs=1e-3 * e["error"]), (name, e, want[name])
        assert abs(e["value"] - want[name]) <= 3.0 * e["error"], (name, e, want[name])
    d1 = est["comp.d1_mm"]
    assert d1["truth_raw"] == pytest.approx(154.5) and abs(d1["truth"] - d1["truth_raw"]) > 3 * d1["error"], d1


def test_reprocess_is_read_only(session):
    db, _ = session
    # other tests' read connections (``with sqlite3.connect`` commits but does not close) checkpoint the WAL into
    # the file whenever the collector closes them: close them now and checkpoint, so only reprocess could change it
    gc.collect()
    c = sqlite3.connect(db)
    c.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    c.close()
    before = db.read_bytes()
    reprocess(str(db))
    assert db.read_bytes() == before


def test_cli_reprocess_json_report_and_export_import(session, tmp_path):
    db, _ = session
    out = tmp_path / "r.json"
    assert main(["reprocess", str(db), "--json", str(out), "--report", str(tmp_path / "rep")]) == 0
    doc = json.loads(out.read_text())
    assert doc["estimates"] and (tmp_path / "rep" / "report.html").stat().st_size > 10_000
    assert main(["sessions", str(db)]) == 0
    poses = tmp_path / "poses.csv"
    rd = tmp_path / "readings.csv"
    assert main(["export", str(db), "--poses", str(poses), "--readings", str(rd), "--json",
                 str(tmp_path / "s.json")]) == 0
    # the pose CSV carries no running-error runs: the set-up names the ones the session measured
    setup = json.loads(sqlite3.connect(db).execute("SELECT setup_json FROM session").fetchone()[0])
    setup["running_errors"] = reprocess(str(db))["figures"]["poses"]["running_errors"]
    assert setup["running_errors"]
    (tmp_path / "setup.json").write_text(json.dumps(setup))
    assert main(["import", str(poses), "--db", str(tmp_path / "imp.db"), "--setup", str(tmp_path / "setup.json")]) == 0
    r2 = reprocess(str(tmp_path / "imp.db"))
    # same poses, isotropic weights instead of the intersection covariances: agree within the estimation errors
    orig = {e["name"]: e for e in doc["estimates"] if e["name"].startswith("ident.")}
    new = {e["name"]: e["value"] for e in r2["estimates"] if e["name"].startswith("ident.")}
    assert new and all(abs(new[k] - orig[k]["value"]) < 4 * orig[k]["error"] + 0.02 for k in new
                       if k.endswith("_mm")), {k: (new[k], orig[k]) for k in new}
    assert main(["import", str(rd), "--db", str(tmp_path / "imp2.db")]) == 0
    r3 = reprocess(str(tmp_path / "imp2.db"))
    e3 = {e["name"]: e["value"] for e in r3["estimates"]}
    assert abs(e3["ruler.L_mm"] - doc["estimates"][0]["value"]) < 1e-6


def test_import_errors_name_the_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("step,procedure,station,target,face,hz_deg,v_deg\nruler/p0/C,ruler,A,C,1,12.5,90\n"
                   "ruler/p0/C,ruler,B,C,3,1,2\n")
    assert main(["import", str(bad), "--db", str(tmp_path / "x.db")]) == 2
    other = tmp_path / "o.csv"
    other.write_text("a,b\n1,2\n")
    assert main(["import", str(other), "--db", str(tmp_path / "y.db")]) == 2


def test_scripted_repeat_and_skip(tmp_path):
    plan = {"procedures": ["ruler"], "ruler": {"repeats": 1}, "seed": 1}
    d = build_demo(tmp_path / "r.db", seed=1, plan=plan,
                   script={"answers": {"ruler/p0/C": ["repeat", "accept"], "ruler/p0/D": ["skip"]}})
    assert d.runner.run() == "finished"
    d.close()
    with sqlite3.connect(tmp_path / "r.db") as c:
        rows = dict(c.execute("SELECT key, status || ':' || attempts FROM step"))
        assert rows["ruler/p0/C"] == "accepted:2" and rows["ruler/p0/D"] == "skipped:1"
        # both attempts' raw readings are kept: 2 attempts x 2 stations x 2 faces
        n = c.execute("SELECT count(*) FROM reading JOIN step USING (step_id) WHERE key='ruler/p0/C'").fetchone()[0]
        assert n == 8


def test_stiff_link_is_reported_as_a_bound_not_a_failure(tmp_path):
    """The default scenario's link has no compliance (the thesis found it negligible against the joints'): the dial
    gauges read noise only, and the result is a 95 % lower bound on EI with the verdict "negligible" -- in the JSON,
    the summary and the report -- not "not determined"."""
    from offline.report import report_html
    from offline.summary import summary_lines
    db = tmp_path / "link.db"
    d = build_demo(db, seed=4, plan={"procedures": ["link_compliance"], "seed": 4})
    assert d.runner.run() == "finished"
    d.close()
    res = reprocess(str(db))
    assert not [p for p in res["problems"] if p.startswith("link")], res["problems"]
    assert not [e for e in res["estimates"] if e["name"].startswith("link.")]
    (b,) = [b for b in res["bounds"] if b["name"] == "link.j2.EI_lower_bound_Nmm2"]
    assert b["side"] == "lower" and b["confidence"] == 0.95 and b["truth"] is None
    assert 0 < b["value"] <= b["detection_limit_Nmm2"]
    assert b["value"] > 2.0e11              # stiffer than the scenario's (disabled) link, which the gauges would see
    lines = [t for _, t in summary_lines(res)]
    head = next(t for t in lines if t.startswith("Link compliance"))
    assert "negligible" in head and "§5.7" in head and "not determined" not in head
    assert any("EI ≥" in t and "95 %" in t for t in lines)
    assert "Verdict: negligible" in report_html(res)
