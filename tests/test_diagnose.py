"""Sim-to-real gap diagnosis (issue 8): engine, library, command, loaders and a reduced withheld-effect study."""
from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from calib.diagnose import diagnose, load_data
from calib.diagnose.candidates import build_library
from calib.diagnose.data import from_arrays
from sim.validate import Case, cases, make_case_data, run_case, run_validation
from calib.errors import RobocalError
from calib.posecsv import write_pose_csv

TIAGO = Path(__file__).resolve().parents[1] / "examples" / "tiago" / "qualysis_base_hand_calibration.csv"
TIAGO_ROBOT = TIAGO.parent / "tiago_mocap.toml"


def _csv(tmp_path, case: Case, with_sigma=True, with_dir=True) -> Path:
    d, _ = make_case_data(case)
    extra = {}
    if with_dir:
        extra.update({f"dir{j + 1}": d.ctx.direction[:, j] for j in range(6)})
    extra["payload"] = d.ctx.payload_kg
    extra["temperature"] = d.ctx.temperature_c
    extra["time"] = d.ctx.time_s
    if with_sigma:
        sig = np.sqrt(np.diagonal(d.cov_mm2, axis1=1, axis2=2))
        extra.update({f"sigma_{c}_mm": sig[:, i] for i, c in enumerate("xyz")})
    p = tmp_path / "poses.csv"
    write_pose_csv(p, d.q_rad, d.points_mm, extra)
    return p


def test_clean_twin_has_no_findings_and_the_gap_sits_on_the_floor():
    r = run_case(Case(None, None, None, 0.0, seed=4242))
    assert r.labels == []
    assert r.baseline_rms_mm < 1.3 * r.noise_floor_mm


def test_withheld_backlash_is_named_first_and_shrinks_the_gap():
    data, _ = make_case_data(Case("backlash", 3, None, 4.0, seed=5))
    diag = diagnose(data, level="full", flag_outliers=False)
    j = diag.to_json()
    first = j["findings"][0]
    assert (first["effect"], first["joint"]) == ("backlash", 3)
    assert first["rms_after_mm"] < j["baseline_rms_mm"]
    assert first["p_value"] < 0.01
    assert first["parameters"]["width_deg"] > 0
    # where it lies: the approach direction of joint 3 is the factor the gap depends on most
    top = min(j["breakdown"], key=lambda f: f["p_value"])
    assert top["factor"] == "joint 3 approach direction" and top["p_value"] < 1e-6
    assert j["final_rms_mm"] < j["baseline_rms_mm"]


def test_reduced_withheld_effect_validation_meets_the_targets():
    """One case per effect kind (mid magnitude) plus clean cases; the full study is ``robocal diagnose --validate``."""
    configs = (("transmission_error", 6, None), ("joint_compliance", 2, None), ("backlash", 5, None),
               ("cross_coupling", 6, 5), ("link_compliance", 4, None), ("thermal_drift", None, None))
    v = run_validation(cases(seeds=1, configs=configs, levels=(3.0,), clean_per_seed=3, n_poses=100, first_seed=7),
                       workers=2)
    assert len(v.effect_results) == 6 and len(v.clean_results) == 3
    assert v.first_right_rate >= 0.95, v.render()
    assert v.false_alarm_rate <= 0.05, v.render()
    assert v.median_shrink >= 0.80, v.render()
    rows, cols, M = v.confusion()
    assert M.sum() == 9 and np.trace(M[:, :len(rows)]) >= 8


def test_library_skips_candidates_whose_driver_is_missing():
    d, _ = make_case_data(Case(None, None, None, 0.0, seed=3, n_poses=30))
    bare = from_arrays(d.robot, d.q_rad, d.points_mm, d.cov_mm2)
    lib = build_library(bare)
    kinds = {c.kind for c in lib.candidates}
    assert "backlash" not in kinds and "thermal_drift" not in kinds
    assert any(s.startswith("backlash") for s in lib.skipped)
    assert any(s.startswith("thermal_drift") for s in lib.skipped)
    full = build_library(d)
    assert {c.kind for c in full.candidates} == {"transmission_error", "joint_compliance", "backlash",
                                                 "backlash_gravity", "cross_coupling", "link_compliance",
                                                 "thermal_drift", "joint_scale", "axis_tilt", "instrument_drift",
                                                 "tool_flex"}
    # without directions, play can only be tested as gravity holds it everywhere (preload 0)
    assert all(c.preload_nm == 0 for c in lib.candidates if c.kind == "backlash_gravity")
    # the Puma's parallel pair (joints 2, 3) already carries the Hayati term: nothing to add
    assert any(s.startswith("parallel_axes: no pair") for s in full.skipped)
    # joint compliance of the vertical waist joint can not be driven by gravity: no signal, held back
    assert any(c.kind == "joint_compliance" and c.joint == 1 for c in full.candidates)


def test_cli_json_has_the_keys_and_names_the_effect(tmp_path, capsys):
    p = _csv(tmp_path, Case("cross_coupling", 6, 5, 4.0, seed=11))
    assert main(["diagnose", str(p), "--json", "--report", str(tmp_path / "rep")]) == 0
    j = json.loads(capsys.readouterr().out)
    for k in ("noise_floor_mm", "baseline_rms_mm", "final_rms_mm", "findings"):
        assert k in j
    f = j["findings"][0]
    assert set(f) >= {"effect", "joint", "rms_after_mm", "p_value", "parameters"}
    assert (f["effect"], f["joint"], f["parameters"]["source_joint"]) == ("cross_coupling", 6, 5)
    assert j["noise_from"] == "data"
    assert (tmp_path / "rep" / "index.html").exists() and (tmp_path / "rep" / "breakdown.png").exists()


def test_cli_text_and_noise_option(tmp_path, capsys):
    p = _csv(tmp_path, Case(None, None, None, 0.0, seed=12, n_poses=60), with_sigma=False, with_dir=False)
    assert main(["diagnose", str(p)]) == 2
    assert "--noise-mm" in capsys.readouterr().err
    assert main(["diagnose", str(p), "--noise-mm", "0.08", "--folds", "4", "--order", "none"]) == 0
    out = capsys.readouterr().out
    assert "1. The gap" in out and "backlash: the data carries no approach directions" in out


@pytest.mark.parametrize("args, msg", [
    (["diagnose", "/nonexistent/poses.csv", "--noise-mm", "0.1"], "file not found"),
    (["diagnose"], "give DATA"),
    (["diagnose", "x.csv", "--noise-mm", "-1"], "--noise-mm must be positive"),
])
def test_cli_errors_are_one_line(args, msg, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert msg in err and "\n" not in err


def test_session_database_hook_refuses_cleanly(tmp_path, capsys):
    db = tmp_path / "s.robocal"
    sqlite3.connect(db).execute("create table t (x)").connection.close()
    assert main(["diagnose", str(db)]) == 2
    assert "not a robocal session database" in capsys.readouterr().err


def test_bad_pose_row_names_file_line_and_column(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("q1,q2,q3,q4,q5,q6,x,y,z\n" + "0,0,0,0,0,0,1,2,3\n" * 9 + "0,0,zero,0,0,0,1,2,3\n")
    with pytest.raises(RobocalError, match=r"bad.csv: line 11: column q3"):
        load_data(p, noise_mm=0.1)


@pytest.mark.skipif(not TIAGO.exists(), reason="TIAGo mocap data set not present")
def test_tiago_mocap_through_the_generic_csv_path_and_geometric_gap():
    from calib.loading import load_robot
    d = load_data(TIAGO, load_robot(TIAGO_ROBOT), noise_mm=0.2, angle_unit="rad", length_unit="m")
    assert d.n == 34 and d.q_rad.shape == (34, 8) and d.robot.prismatic[0]
    assert 0 < d.q_rad[:, 0].min() and d.q_rad[:, 0].max() < 360            # torso lift in mm, not m
    diag = diagnose(d, level="offsets", max_effects=0, flag_outliers=False)
    # the description is right to a few mm: FIGAROH reports ~3-4 mm after calibration on this set-up
    assert 1.0 < diag.baseline_rms_mm < 10.0


def test_tiago_bad_row(tmp_path):
    text = TIAGO.read_text().splitlines() if TIAGO.exists() else None
    if text is None:
        pytest.skip("TIAGo mocap data set not present")
    bad = text[:5] + [text[5].replace(text[5].split(",")[13], "nan", 1)] + text[6:]
    p = tmp_path / "t.csv"
    p.write_text("\n".join(bad) + "\n")
    from calib.loading import load_robot
    with pytest.raises(RobocalError, match=r"line 6: column arm_1_joint"):
        load_data(p, load_robot(TIAGO_ROBOT), noise_mm=0.2, angle_unit="rad", length_unit="m")


@pytest.mark.parametrize("args, msg", [
    (["diagnose", "--validate", "--levels", "two"], "--levels must be numbers"),
    (["diagnose", "--validate", "--seeds", "0"], "--seeds must be at least 1"),
])
def test_validate_option_errors(args, msg, capsys):
    assert main(args) == 2
    assert msg in capsys.readouterr().err


def test_outliers_reject_blunders_and_identify_gives_the_same_geometric_fit():
    from calib.diagnose.gap import geometric_free
    from calib.identify import identify
    from calib.model import MeasurementModel

    d, _ = make_case_data(Case(None, None, None, 0.0, seed=21, n_poses=80))
    bad = [5, 33, 61]
    d.points_mm[bad] += [2.0, -3.0, 2.5]
    diag = diagnose(d, level="full", max_effects=0, outliers="reject")
    j = diag.to_json()
    assert j["outliers"]["rejected"] == [i + 1 for i in bad] and j["outliers"]["cluster"] is None
    assert diag.data.n == 77
    model = MeasurementModel(d.robot)
    idn = identify(model, d.observations(), free=geometric_free(model, "full"), outliers="reject")
    P = model.P
    q = d.q_rad[:20]
    gap = model.points(q, theta=idn.theta[:P]) - model.points(q, theta=diag.geometric.all_fit.theta[:P])
    assert np.abs(gap).max() < 1e-3
    flag = diagnose(d, level="full", max_effects=0).to_json()["outliers"]
    assert flag["mode"] == "flag" and flag["flagged"] == [i + 1 for i in bad] and flag["rejected"] == []


def test_outlier_numbering_is_the_files_in_identify_and_diagnose_json_and_terminal(tmp_path, capsys):
    """identify's JSON used to list 0-based indices of the fitted rows (and not say which were rejected), diagnose's
    1-based rows: both now name a flagged pose by its 1-based data row and the file's pose id, and mark it rejected.
    The file has a split with test rows first, so a fitted-row index is not a file row."""
    d, _ = make_case_data(Case(None, None, None, 0.0, seed=21, n_poses=80))
    bad = [25, 53, 71]                      # 0-based file rows, all in the fit part
    d.points_mm[bad] += [2.0, -3.0, 2.5]
    sig = np.sqrt(np.diagonal(d.cov_mm2, axis1=1, axis2=2))
    p = tmp_path / "ids.csv"
    write_pose_csv(p, d.q_rad, d.points_mm, {f"sigma_{c}_mm": sig[:, i] for i, c in enumerate("xyz")})
    lines = p.read_text().splitlines()
    lines[0] += ",pose,split"
    for i in range(1, len(lines)):
        lines[i] += f",P{i:03d}," + ("test" if i <= 20 else "fit")
    p.write_text("\n".join(lines) + "\n")
    want_rows = [i + 1 for i in bad]
    want_ids = [f"P{i + 1:03d}" for i in bad]
    assert main(["identify", str(p), "--json", "--outliers", "reject"]) == 0
    ij = json.loads(capsys.readouterr().out)
    assert [o["row"] for o in ij["outliers"]] == want_rows, ij["outliers"]
    assert [o["pose_id"] for o in ij["outliers"]] == want_ids and all(o["rejected"] for o in ij["outliers"])
    assert ij["outlier_report"]["rejected"] == want_rows
    assert main(["diagnose", str(p), "--json", "--outliers", "reject", "--max-effects", "0"]) == 0
    dj = json.loads(capsys.readouterr().out)
    assert dj["outliers"]["poses"] == ij["outliers"] and dj["outliers"]["flagged"] == want_rows
    assert dj["gross_errors_flagged"] == want_rows
    assert main(["identify", str(p), "--outliers", "reject"]) == 0
    assert "left out: poses " + ", ".join(want_ids) in capsys.readouterr().out
