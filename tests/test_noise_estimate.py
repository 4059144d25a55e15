"""The measurement noise from the data (calib.noise, shared by identify and diagnose), against truth made elsewhere.

The data come from the independent generators in tests/fakes/ (plain numpy products of the thesis's formulas, nothing
from calib): a Puma carrying two or three targets with known Gaussian noise, optionally with a joint compliance the
fitted model lacks; theodolite readings on both faces of instruments out of adjustment.
"""
from __future__ import annotations

import dataclasses
import json
from importlib import resources

import numpy as np
import pytest

from app.cli import main
from calib import noise
from calib.theodolite import thesis_stations
from tests.fakes.thesis_procedures import ARCSEC, sightings
from tests.fakes.thesis_puma import JointCompliance, ThesisPuma, true_points

PUMA_TOML = resources.files("calib") / "data" / "puma560.toml"
#: tool points in frame 6 (mm): targets rigidly fixed to the tool
TOOLS = {"T1": (0.0, 0.0, 40.0), "T2": (60.0, 5.0, 30.0), "T3": (-20.0, 70.0, 25.0)}
COMPLIANCE = (JointCompliance(3, 2e3),)            # N m / rad: millimetres at the tool under gravity


def _arm() -> ThesisPuma:
    return ThesisPuma.from_toml(PUMA_TOML)


def _measured(seed: int, n: int, k: int, sigma: float, effects=()) -> tuple[np.ndarray, np.ndarray]:
    """Joint readings (n, 6) and measured targets (n, k, 3): the fake Puma's points plus Gaussian noise."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1.4, 1.4, (n, 6))
    arm = _arm()
    pts = [true_points(dataclasses.replace(arm, tool_xyz_t=tuple(-np.array(t))), q, effects)[0]
           for t in list(TOOLS.values())[:k]]
    return q, np.stack(pts, 1) + rng.normal(0.0, sigma, (n, k, 3))


def _rows(P: np.ndarray):
    n, k = P.shape[:2]
    return (P.reshape(-1, 3), [str(i) for i in range(n) for _ in range(k)],
            [name for _ in range(n) for name in list(TOOLS)[:k]])


@pytest.mark.parametrize("k", [2, 3])
def test_target_distances_find_the_true_noise_not_the_given_one(k):
    sigma, given = 0.03, 0.08
    got = []
    for seed in range(6):
        _, P = _measured(seed, 50, k, sigma)
        pts, pose, tgt = _rows(P)
        cov = np.broadcast_to(np.eye(3) * given ** 2, (len(pts), 3, 3))
        s = noise.from_target_distances(pose, tgt, pts, cov)
        assert s is not None and s.dof == (50 - 1) * (1 if k == 2 else 3)
        got.append(np.sqrt(s.var_mm2))
    got = np.array(got)
    # sampling spread of a sigma with f degrees of freedom is sigma / sqrt(2 f): 10 % (k = 2), 6 % (k = 3)
    assert np.all(np.abs(got / sigma - 1) < 0.3), got
    assert abs(np.mean(got) / sigma - 1) < 0.1, got


def test_anisotropic_covariances_are_used():
    """Points whose z is 3x noisier than x, y (as a theodolite pair gives): with the covariance the estimate is the
    scale of that covariance, whatever direction the targets' separation points in."""
    rng_scale = []
    for seed in range(5):
        rng = np.random.default_rng(100 + seed)
        _, P = _measured(seed, 60, 2, 0.0)
        sd = np.array([0.02, 0.02, 0.06])
        P = P + rng.normal(0.0, 1.0, P.shape) * sd
        pts, pose, tgt = _rows(P)
        cov = np.broadcast_to(np.diag(sd ** 2), (len(pts), 3, 3))
        s = noise.from_target_distances(pose, tgt, pts, cov)
        rng_scale.append(s.var_mm2 / np.mean(sd ** 2))      # 1 when the covariance is right
    assert abs(np.mean(rng_scale) - 1) < 0.15, rng_scale


def test_a_systematic_effect_does_not_move_it_but_moves_the_residual_bound(tmp_path, capsys):
    sigma = 0.03
    _, P0 = _measured(7, 60, 2, sigma)
    _, P1 = _measured(7, 60, 2, sigma, COMPLIANCE)
    assert np.abs(P1 - P0).max() > 0.5                     # the compliance moves the tool by more than 0.5 mm
    est = []
    for P in (P0, P1):
        pts, pose, tgt = _rows(P)
        cov = np.broadcast_to(np.eye(3) * sigma ** 2, (len(pts), 3, 3))
        est.append(np.sqrt(noise.from_target_distances(pose, tgt, pts, cov).var_mm2))
    assert abs(est[1] / est[0] - 1) < 0.01, est
    # identify, geometry only, on the compliant data: the model-free estimate is right; the residual is only a bound
    q, _ = _measured(7, 60, 2, sigma)
    desc = _description(tmp_path)
    two = _wide_csv(tmp_path / "two.csv", q, P1)
    one = _wide_csv(tmp_path / "one.csv", q, P1[:, :1])
    j2 = _identify(capsys, two, desc, sigma)
    j1 = _identify(capsys, one, desc, sigma)
    assert not j2["noise_estimate"]["upper_bound"] and "target distances" in j2["noise_estimate"]["from"]
    assert abs(j2["noise_estimated_mm"] / sigma - 1) < 0.3
    assert j1["noise_estimate"]["upper_bound"] and j1["noise_estimated_mm"] > 1.5 * sigma


def _description(tmp_path) -> str:
    path = tmp_path / "puma_targets.toml"
    path.write_text(PUMA_TOML.read_text(encoding="utf-8") + "".join(
        f"{name} = [{', '.join(str(v) for v in p)}]\n" for name, p in TOOLS.items()), encoding="utf-8")
    return str(path)


def _wide_csv(path, q, P) -> str:
    """Several targets per row: x<T>, y<T>, z<T> columns."""
    k = P.shape[1]
    names = list(TOOLS)[:k]
    lines = [",".join([f"q{j}" for j in range(1, 7)] + [f"{a}{t}" for t in names for a in "xyz"])]
    for qi, pi in zip(np.degrees(q), P):
        lines.append(",".join(f"{v:.9f}" for v in qi) + "," + ",".join(f"{v:.6f}" for v in pi.ravel()))
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def _identify(capsys, csv, desc, noise_mm, expect_warning: bool | None = None) -> dict:
    rc = main(["identify", csv, "--robot", desc, "--noise-mm", str(noise_mm), "--json"])
    out = capsys.readouterr()
    assert rc == 0, out.err
    warned = [ln for ln in out.err.splitlines() if "the given noise" in ln]
    if expect_warning is not None:
        assert bool(warned) == expect_warning, out.err
        assert len(warned) <= 1
    return json.loads(out.out)


@pytest.mark.parametrize("factor, warns", [(1.0, False), (3.0, True), (1 / 3, True)])
def test_identify_warns_when_the_given_noise_is_3x_off(tmp_path, capsys, factor, warns):
    sigma = 0.03
    q, P = _measured(3, 40, 3, sigma)
    csv = _wide_csv(tmp_path / "three.csv", q, P)
    j = _identify(capsys, csv, _description(tmp_path), sigma * factor, expect_warning=warns)
    assert j["noise_estimate"]["given_mm"] == pytest.approx(sigma * factor)
    assert abs(j["noise_estimated_mm"] / sigma - 1) < 0.25
    assert not j["noise_estimate"]["upper_bound"]


def test_inconsistent_targets_per_pose_fall_back_instead_of_failing():
    """Poses with different target sets, single targets, a target twice, two targets at one spot: what can be
    used is used, the rest left out, nothing raises."""
    sigma = 0.03
    q, P = _measured(11, 30, 3, sigma)
    rows, pose, tgt = [], [], []
    for i in range(30):
        pick = [(0, 1), (0,), (1, 2), (0, 0), (0, 1, 2)][i % 5]
        for t in pick:
            rows.append(P[i, t])
            pose.append(f"p{i}")
            tgt.append(list(TOOLS)[t])
    rows = np.array(rows)
    cov = np.broadcast_to(np.eye(3) * sigma ** 2, (len(rows), 3, 3))
    qr = np.array([q[int(p[1:])] for p in pose])
    found = noise.model_free(qr, rows, cov, pose_id=pose, target=tgt)
    assert [s.how.split(" (")[0] for s in found] == ["repeats", "target distances"]
    # only unusable sets: no model-free source, the residual bound is what is left
    bad_rows = np.repeat(P[:5, 0], 2, axis=0)
    none = noise.model_free(np.repeat(q[:5], 2, axis=0) + np.arange(10)[:, None], bad_rows,
                            np.broadcast_to(np.eye(3) * sigma ** 2, (10, 3, 3)),
                            pose_id=[f"p{i // 2}" for i in range(10)], target=["T1", "T1"] * 5)
    assert none == []
    e = noise.combine(sigma, none, 0.05)
    assert e.upper_bound and e.estimated_mm == 0.05
    # nonsense inputs (a label list of the wrong length) leave the source out, they do not raise
    assert noise.model_free(q, P[:, 0], np.broadcast_to(np.eye(3) * sigma ** 2, (30, 3, 3)), target=["T1"]) == []


def test_sources_pool_by_degrees_of_freedom():
    a, b = noise.Sample("a", 1.0, 10), noise.Sample("b", 4.0, 30)
    e = noise.combine(2.0, [a, b], 99.0)
    assert e.estimated_mm == pytest.approx(np.sqrt((10 * 1 + 30 * 4) / 40))
    assert e.how == "a + b" and not e.upper_bound and len(e.as_dict()["sources"]) == 2


# -- both faces --------------------------------------------------------------------------------------------------------
L_MM, G1, G2 = 2500.0, -1.489 * np.pi / 180, 1.358 * np.pi / 180


def _face_sightings(seed: int, n: int, sigma_rad: float) -> noise.Sightings:
    rng = np.random.default_rng(seed)
    P = np.column_stack([rng.uniform(400, 2100, n), rng.uniform(900, 2200, n), rng.uniform(-300, 700, n)])
    readings, target = [], []
    for i in range(n):
        readings.append(sightings(P[i:i + 1], ["P"], L_MM, G1, G2, 0.0, sigma_rad, rng,
                                  collimation=(25 * ARCSEC, -15 * ARCSEC), index=(12 * ARCSEC, -30 * ARCSEC)))
        target.append("P")
    a, b = thesis_stations(L_MM, G1, G2, 3 * ARCSEC)
    a, b = (dataclasses.replace(s, collimation_rad=c, index_rad=k)
            for s, c, k in ((a, 25 * ARCSEC, 12 * ARCSEC), (b, -15 * ARCSEC, -30 * ARCSEC)))
    return noise.Sightings(readings, target, {"A": a, "B": b})


def test_both_faces_give_each_stations_angular_noise_despite_collimation_and_index_errors():
    sigma = 2.0 * ARCSEC
    got = []
    for seed in range(5):
        per = noise.station_noise(_face_sightings(seed, 60, sigma))
        assert set(per) == {"A", "B"}
        assert all(f_h == 58 and f_v == 59 for _, _, f_h, f_v in per.values())
        got += [v for st in per.values() for v in st[:2]]
    got = np.array(got) / sigma
    assert np.all(np.abs(got - 1) < 0.35), got
    assert abs(np.mean(got) - 1) < 0.08, got
    # without removing the instrument errors the 25" collimation would dominate: the fit removed it
    assert np.max(got) < 1.35


def test_both_faces_reach_mm_through_the_intersection():
    """The estimate in mm is the intersection's covariance with the estimated angular noise: 2" read as 2", not the
    stations' nominal 3", so the mm figure is 2/3 of the nominal one (to the sampling spread)."""
    s = _face_sightings(1, 60, 2.0 * ARCSEC)
    got = noise.from_faces(s)
    nominal = noise.from_faces(dataclasses.replace(s), None)
    assert got is not None and "both faces" in got.how and got.dof == 2 * (58 + 59)
    from calib.estimators.points import StationFit, locate_targets
    pts = locate_targets([{**r, "target": f"{i}"} for i, rs in enumerate(s.readings) for r in rs],
                         StationFit.exact(s.stations))
    at_3 = np.mean([np.trace(p.cov_reading_mm2) / 3 for p in pts.values()])
    assert np.sqrt(got.var_mm2 / at_3) == pytest.approx(2 / 3, rel=0.12)
    assert nominal.var_mm2 == pytest.approx(got.var_mm2)
    # a pose read on one face only, or by one station only, is left out of the face differences
    s.readings[0] = [r for r in s.readings[0] if r["face"] == 1]
    s.readings[1] = [r for r in s.readings[1] if r["station"] == "A"]
    per = noise.station_noise(s)
    assert per["A"][2] == 57 and per["B"][2] == 56


def test_a_blunder_is_left_out_of_the_distances():
    sigma = 0.03
    _, P = _measured(5, 60, 2, sigma)
    pts, pose, tgt = _rows(P)
    cov = np.broadcast_to(np.eye(3) * sigma ** 2, (len(pts), 3, 3))
    clean = noise.from_target_distances(pose, tgt, pts, cov)
    pts = pts.copy()
    pts[20] += [0.0, 0.0, 1.0]                              # one target of pose 10 read 1 mm off
    s = noise.from_target_distances(pose, tgt, pts, cov)
    assert "1 left out" in s.how and s.dof == clean.dof - 1
    assert abs(np.sqrt(s.var_mm2) / sigma - 1) < 0.3


def test_the_diagnosis_reads_several_targets_per_pose_from_a_pose_csv(tmp_path):
    from calib.diagnose import noise as dnoise
    from calib.diagnose.data import load_data
    from calib.loading import load_robot

    sigma = 0.03
    q, P = _measured(9, 40, 2, sigma, COMPLIANCE)
    data = load_data(_wide_csv(tmp_path / "two.csv", q, P), load_robot(_description(tmp_path)), noise_mm=0.1)
    e = dnoise.estimate(data, heldout_rms_mm=1.0)
    assert not e.upper_bound and "target distances (40 poses" in e.how
    assert abs(e.estimated_mm / sigma - 1) < 0.3 and e.given_too_large


def _weights_of(csv: str, desc: str):
    """identify's noise decision on a wide CSV (no --noise-mm): the fit rows' table and its Weights."""
    from app.commands.identify import _Fit
    from calib.evaluation import context_of, fit_rows, point_covariance
    from calib.fitreport import Weights
    from calib.identify import PointObservations, default_free
    from calib.model import MeasurementModel
    from calib.posecsv import read_pose_csv
    from calib.loading import load_robot
    robot = load_robot(desc)
    table, robot, offsets = fit_rows(read_pose_csv(csv, robot.n, robot.prismatic, robot=robot), robot)
    model = MeasurementModel(robot, offsets)
    obs = PointObservations(table.q_rad, table.points_mm, point_covariance(table), sigma_mm=1.0,
                            ctx=context_of(model, table))
    fit = _Fit(model, default_free(model), [], None, True, "flag", "linear", "auto")
    return Weights.decide(table, obs, None, fit)


def test_a_folds_noise_comes_from_its_own_rows(tmp_path):
    """The model-free noise (target distances) a cross-validation fold weighs its rows by is estimated on its fit
    rows alone: making the test rows four times noisier changes the all-row estimate, not the fold's weights of its
    fit rows or of its test rows."""
    desc = _description(tmp_path)
    q, P = _measured(3, 40, 2, 0.03)
    noisy = P.copy()
    test = np.arange(0, 40, 5)
    noisy[test] += np.random.default_rng(4).normal(0.0, 0.12, noisy[test].shape)
    train = np.setdiff1d(np.arange(40), test)
    w_clean = _weights_of(_wide_csv(tmp_path / "clean.csv", q, P), desc)
    w_noisy = _weights_of(_wide_csv(tmp_path / "noisy.csv", q, noisy), desc)
    assert w_clean.how.startswith("target distances") and w_noisy.how.startswith("target distances")
    assert w_noisy.sigma_mm > 1.1 * w_clean.sigma_mm          # the all-row estimate sees the noisy rows
    rows = lambda idx: np.concatenate([2 * idx, 2 * idx + 1])   # two targets a pose: rows 2i, 2i+1
    for a, b in zip(w_clean.fold(rows(train), rows(test)), w_noisy.fold(rows(train), rows(test))):
        np.testing.assert_allclose(a.cov_mm2, b.cov_mm2, rtol=1e-9)
    sigma = np.sqrt(w_clean.fold(rows(train), rows(test))[0].cov_mm2[0, 0, 0])
    assert abs(sigma / 0.03 - 1) < 0.35


def _rigid(P: np.ndarray, sigma: float, seed: int) -> np.ndarray:
    """The targets of each pose moved as one rigid body by a random rotation (sigma / 100 mm rad) and translation
    (sigma mm): a marker set solved as a body, whose virtual points share all their noise (plain numpy: Rodrigues)."""
    rng = np.random.default_rng(seed)
    out = np.empty_like(P)
    for i, pts in enumerate(P):
        w = rng.normal(0.0, sigma / 100.0, 3)
        a = np.linalg.norm(w)
        K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / a
        R = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
        c = pts.mean(0)
        out[i] = (pts - c) @ R.T + c + rng.normal(0.0, sigma, 3)
    return out


@pytest.mark.parametrize("given", [True, False])
def test_targets_moving_as_one_rigid_body_are_set_aside_not_read_as_noise(given):
    """Virtual points of a solved marker set (motion capture's rigid bodies; TIAGo's Qualisys export) keep their
    distances to the last digit whatever the noise: the distances say nothing about it, and an estimate of 1e-5 mm
    would put the floor at zero.  With a given noise (0.2 mm, 21,000x the scatter) or without one (the scatter is
    1e-8 of the distances), the source is set aside with its reason; the estimate falls back to the bound."""
    sigma = 0.2
    _, P = _measured(21, 40, 3, 0.0)
    pts, pose, tgt = _rows(_rigid(P, sigma, 21))
    cov = np.broadcast_to(np.eye(3) * (sigma if given else 1.0) ** 2, (len(pts), 3, 3))
    q = np.repeat(np.arange(40.0), 3)[:, None] * np.ones(6)
    found = noise.model_free(q, pts, cov, pose_id=pose, target=tgt, given=given)
    assert [s.how.split(" (")[0] for s in found] == ["target distances"]
    assert np.sqrt(found[0].var_mm2) < 1e-3 * sigma and "rigid body" in found[0].set_aside
    e = noise.combine(sigma, found, 0.5)
    assert e.upper_bound and e.estimated_mm == 0.5 and e.sources == [] and e.set_aside == found
    assert "rigid body" in e.set_aside_lines()[0] and e.as_dict()["set_aside"][0]["set_aside"]
    assert e.floor_scale() == 1.0                           # 0.2 given < 0.5 bound: the given floor stands


def test_independent_targets_are_not_set_aside_even_when_the_given_noise_is_10x_off():
    _, P = _measured(22, 40, 2, 0.02)
    pts, pose, tgt = _rows(P)
    cov = np.broadcast_to(np.eye(3) * 0.2 ** 2, (len(pts), 3, 3))
    s = noise.from_target_distances(pose, tgt, pts, cov)
    assert s.set_aside == "" and abs(np.sqrt(s.var_mm2) / 0.02 - 1) < 0.3
    e = noise.combine(0.2, [s])
    assert not e.upper_bound and e.given_too_large and e.set_aside == []


def test_identify_without_a_noise_on_a_rigid_marker_set_says_so(tmp_path, capsys):
    """No --noise-mm, targets from one rigid body: the errors are scaled by the residual, and the noise line names
    the set-aside source instead of "one target per pose"."""
    q, P = _measured(23, 40, 3, 0.0)
    csv = _wide_csv(tmp_path / "rigid.csv", q, _rigid(P, 0.2, 23))
    rc = main(["identify", csv, "--robot", _description(tmp_path), "--json"])
    out = capsys.readouterr()
    assert rc == 0, out.err
    j = json.loads(out.out)
    assert j["noise"]["errors_scaled_by_residual"] and "rigid body" in j["noise"]["set_aside"][0]
