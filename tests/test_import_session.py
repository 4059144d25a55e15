"""``robocal import``: what a pose CSV or a readings CSV measured reaches the stored session, reprocess and diagnose.

Truth: an independent Puma (tests/fakes/thesis_puma, plain matrix products of the thesis's formulas) gives the points;
the file's own sigma columns, conditions and labels must come back out of the session as written."""
from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest

from app.cli import main
from offline.exchange import pose_arrays
from app.reprocess import load_session, reprocess
from acq.session.setup import standard_setup
from tests.fakes.thesis_puma import ThesisPuma, base_matrix

PUMA = resources.files("calib") / "data" / "puma560.toml"


def _pose_csv(path, sigma_mm, n=30, seed=3):
    """A pose CSV of ``n`` poses of the independent Puma, noise drawn with per-row, per-axis ``sigma_mm`` (n, 3)."""
    rng = np.random.default_rng(seed)
    arm = ThesisPuma.from_toml(PUMA)
    arm.base = base_matrix(standard_setup()["base_xyz_mm"])
    q = rng.uniform(-60, 60, (n, 6)) * np.pi / 180
    pts = np.array([arm.tool_point(qi) for qi in q]) + rng.normal(size=(n, 3)) * sigma_mm
    lines = ["q1,q2,q3,q4,q5,q6,x,y,z,sigma_x_mm,sigma_y_mm,sigma_z_mm,time,payload,station,split,pose,operator_note"]
    for i in range(n):
        split = "test" if i % 4 == 0 else "fit"
        cells = [f"{v:.6f}" for v in np.degrees(q[i])] + [f"{v:.6f}" for v in pts[i]]
        cells += [f"{v:.4f}" for v in sigma_mm[i]] + [f"{10.0 * i:.1f}", f"{i % 3:.1f}", "T1", split, f"p{i:02d}",
                                                      f"note {i}"]
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture()
def sigmas():
    rng = np.random.default_rng(7)
    return rng.uniform(0.02, 0.3, (30, 3))


def test_pose_import_keeps_every_column(tmp_path, sigmas):
    src = _pose_csv(tmp_path / "p.csv", sigmas)
    assert main(["import", str(src), "--db", str(tmp_path / "i.db")]) == 0
    steps = load_session(str(tmp_path / "i.db")).steps
    assert len(steps) == 30
    rows = src.read_text().splitlines()
    header = rows[0].split(",")
    for i, st in enumerate(steps):
        imp = st["spec"]["imported"]
        assert imp["row"] == dict(zip(header, rows[i + 1].split(",")))          # the row as written
        assert imp["labels"] == {"station": "T1", "split": "test" if i % 4 == 0 else "fit", "pose": f"p{i:02d}"}
        assert [st["inputs"][f"sigma_{c}_mm"] for c in "xyz"] == pytest.approx(sigmas[i], abs=1e-4)
        assert st["inputs"]["time_s"] == pytest.approx(10.0 * i)


def test_imported_session_uses_the_files_sigmas_and_conditions(tmp_path, sigmas):
    src = _pose_csv(tmp_path / "p.csv", sigmas)
    assert main(["import", str(src), "--db", str(tmp_path / "i.db")]) == 0
    a = pose_arrays(str(tmp_path / "i.db"))
    assert np.sqrt(np.diagonal(a["cov_mm2"], axis1=1, axis2=2)) == pytest.approx(sigmas, abs=1e-4)
    assert a["time_s"] == pytest.approx(10.0 * np.arange(30))
    assert a["payload_kg"] == pytest.approx(np.arange(30) % 3)
    assert a["split"][:4] == ["test", "fit", "fit", "fit"] and a["pose"][1] == "p01"
    from calib.diagnose.data import from_session_arrays
    from calib.loading import load_robot
    d = from_session_arrays(load_robot(), a, "i.db")
    assert d.split == a["split"] and d.has["payload"] and d.noise_from == "data"


def test_reprocess_weights_imported_points_by_their_sigmas(tmp_path):
    """The same points imported with sigma 0.05 and 0.5 mm: the identified parameters' errors differ tenfold (with
    the old 0.05 mm default for every imported point they would be equal)."""
    errs = []
    for k, s in enumerate((0.05, 0.5)):
        src = _pose_csv(tmp_path / f"p{k}.csv", np.full((30, 3), s))
        assert main(["import", str(src), "--db", str(tmp_path / f"i{k}.db")]) == 0
        res = reprocess(str(tmp_path / f"i{k}.db"))
        errs.append({e["name"]: e["error"] for e in res["estimates"] if e["name"].startswith("ident.")
                     and not e["held"]})
    ratio = np.array([errs[1][n] / errs[0][n] for n in errs[0]])
    assert ratio.size > 5 and np.median(ratio) == pytest.approx(10.0, rel=0.1), ratio


def test_reprocess_refuses_several_targets_per_pose(tmp_path):
    src = _pose_csv(tmp_path / "p.csv", np.full((30, 3), 0.05))
    rows = src.read_text().splitlines()
    rows[0] = rows[0].replace("station", "target")
    rows[1:] = [r.replace(",T1,", ",1,") if i % 2 else r.replace(",T1,", ",2,") for i, r in enumerate(rows[1:])]
    src.write_text("\n".join(rows) + "\n")
    assert main(["import", str(src), "--db", str(tmp_path / "i.db")]) == 0
    problems = reprocess(str(tmp_path / "i.db"))["problems"]
    assert any("2 targets (1, 2)" in p for p in problems), problems        # a failed stage in words, no wrong fit


def _ruler_readings(path, names, setup):
    """A raw-readings CSV of the set-up's ruler placements, both faces, by the independent thesis geometry."""
    from tests.fakes.thesis_puma import leica_readings
    st = setup["stations"]
    lines = ["step,procedure,station,target,face,hz_deg,v_deg"]
    from acq.session.setup_types import mark_index, mark_names
    marks_mm = setup["ruler"]["marks_mm"]
    for k, pl in enumerate(setup["ruler"]["placements"]):
        d = np.asarray(pl["dir"], float) / np.linalg.norm(pl["dir"])
        for mark in pl.get("marks", mark_names(len(marks_mm))):
            p = np.asarray(pl["C_mm"], float) + marks_mm[mark_index(mark)] * d
            r = np.degrees(leica_readings(p[None], st["L_mm"], np.radians(st["gamma1_deg"]),
                                          np.radians(st["gamma2_deg"]))[0])
            for s, (hz, v) in zip(names, (r[:2], r[2:])):
                for face, (h, vv) in ((1, (hz, v)), (2, ((hz + 180) % 360, 360 - v))):
                    lines.append(f"ruler/p{k}/{mark},ruler,{s},{mark},{face},{h:.8f},{vv:.8f}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_readings_import_takes_the_setups_station_names(tmp_path, capsys):
    setup = standard_setup()
    setup["stations"] = {**setup["stations"], "names": ["West", "East"], "L_mm": 1723.0}
    (tmp_path / "setup.json").write_text(json.dumps(setup))
    src = _ruler_readings(tmp_path / "r.csv", ["West", "East"], setup)
    assert main(["import", str(src), "--db", str(tmp_path / "r.db"), "--setup", str(tmp_path / "setup.json")]) == 0
    est = {e["name"]: e["value"] for e in reprocess(str(tmp_path / "r.db"))["estimates"]}
    assert est["ruler.L_mm"] == pytest.approx(1723.0, abs=1e-3)
    stored = {r["station"] for s in load_session(str(tmp_path / "r.db")).steps for r in s["readings"]}
    assert stored == {"West", "East"}
    # a station the set-up does not name: one line with the file, the line and the column
    capsys.readouterr()
    assert main(["import", str(src), "--db", str(tmp_path / "d.db")]) == 2       # default set-up: A and B
    err = capsys.readouterr().err.strip()
    assert err == (f"robocal: error: {src}: line 2: column station: 'West' is not a station of the set-up "
                   "(its stations: A, B)")
    assert not (tmp_path / "d.db").exists()


def test_export_gives_back_what_the_import_kept(tmp_path, sigmas, capsys):
    from calib.posecsv import read_pose_csv
    src = _pose_csv(tmp_path / "p.csv", sigmas)
    assert main(["import", str(src), "--db", str(tmp_path / "i.db")]) == 0
    assert "operator_note kept in the session" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "i.db"), "--poses", str(tmp_path / "back.csv")]) == 0
    with pytest.warns(UserWarning, match="operator_note"):
        a = read_pose_csv(src)
    b = read_pose_csv(tmp_path / "back.csv")
    np.testing.assert_allclose(b.q_rad, a.q_rad, atol=1e-7)
    np.testing.assert_allclose(b.points_mm, a.points_mm, atol=1e-6)
    np.testing.assert_allclose(b.sigma_mm, a.sigma_mm, atol=1e-6)
    np.testing.assert_allclose(b.time_s, a.time_s)
    np.testing.assert_allclose(b.payload_kg, a.payload_kg)
    assert (b.station, b.split, b.pose_id) == (a.station, a.split, a.pose_id)
