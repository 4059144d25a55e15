"""identify with the data's own split, --free and priors; evaluate and locate -- on data Pinocchio generated from a
perturbed URDF (an independent implementation of the chain), measured from two instrument set-ups."""
import json
from pathlib import Path

import numpy as np
import pytest

from tests.dev_extra import require
from tests.fakes.oracle.chain import rpy_matrix

from app.cli import main

pin = require("pinocchio", "pin")
EX = Path(__file__).resolve().parents[1] / "examples"
NAMES = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]


def _truth_urdf(tmp_path):
    """The UR10 with its forearm 3 mm longer and the elbow origin 2 mm off sideways: a real robot."""
    text = (EX / "urdf" / "ur10_robot.urdf").read_text()
    elbow = text.index('<joint name="elbow_joint" type=')
    head, tail = text[:elbow], text[elbow:]
    i = tail.index('xyz="') + 5
    j = tail.index('"', i)
    x, y, z = (float(v) for v in tail[i:j].split())
    tail = tail[:i] + f"{x - 0.003} {y + 0.002} {z}" + tail[j:]
    f = tmp_path / "truth.urdf"
    f.write_text(head + tail)
    return f


def _measure(urdf, q, T=np.eye(4), seed=0, noise=0.01):
    """The origin of wrist_3_link (Pinocchio) in the instrument frame T, with noise."""
    return _measure_points(urdf, q, np.zeros((1, 3)), T, seed, noise)[:, 0]


def _write(path, q, p, extra=None):
    extra = extra or {}
    cols = NAMES + ["x", "y", "z"] + list(extra)
    lines = [",".join(cols)]
    for i in range(len(q)):
        vals = [f"{v:.9f}" for v in np.degrees(q[i])] + [f"{v:.6f}" for v in p[i]] + [str(extra[k][i]) for k in extra]
        lines.append(",".join(vals))
    path.write_text("\n".join(lines) + "\n")
    return path


def _run(capsys, argv):
    rc = main(argv)
    out = capsys.readouterr()
    assert rc == 0, out.err
    return out.out


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rd")
    rng = np.random.default_rng(11)
    q = rng.uniform(-2.5, 2.5, (60, 6))
    T1 = np.eye(4)
    T1[:3, :3], T1[:3, 3] = rpy_matrix(0.01, -0.02, 0.6), [1500.0, -300.0, 200.0]
    truth = _truth_urdf(tmp)
    split = ["fit"] * 40 + ["test"] * 20
    data = _write(tmp / "s1.csv", q, _measure(truth, q, T1, 1), {"split": split, "station": ["S1"] * 60})
    return tmp, truth, q, T1, data


def test_identify_reports_the_held_out_split_and_evaluate_agrees(world, capsys):
    tmp, truth, q, T1, data = world
    model = tmp / "m.json"
    doc = json.loads(_run(capsys, ["identify", str(data), "--robot", str(EX / "urdf" / "ur10_robot.urdf"),
                                   "--noise-mm", "0.01", "--out", str(model), "--json"]))
    assert doc["n_fit"] == 40 and doc["n_test"] == 20
    # the geometric error is inside the chain's parametrisation: held-out poses are predicted to the noise
    assert doc["test_rms_mm"] < 0.05 and doc["fit_rms_mm"] < 0.05 and doc["test_max_mm"] < 0.1
    ev = json.loads(_run(capsys, ["evaluate", str(model), str(data), "--json"]))
    assert ev["n"] == 20 and ev["rms_mm"] == pytest.approx(doc["test_rms_mm"], rel=1e-6)
    assert set(ev["by"]["station"]) == {"S1"}


def test_locate_finds_a_new_station(world, capsys):
    tmp, truth, q, T1, data = world
    model = tmp / "m2.json"
    _run(capsys, ["identify", str(data), "--robot", str(EX / "urdf" / "ur10_robot.urdf"), "--noise-mm", "0.01",
                  "--out", str(model)])
    T2 = np.eye(4)
    T2[:3, :3], T2[:3, 3] = rpy_matrix(-0.03, 0.01, -1.1), [-800.0, 2200.0, -50.0]
    d2 = _write(tmp / "s2.csv", q[:15], _measure(truth, q[:15], T2, 2), {"station": ["S2"] * 15})
    doc = json.loads(_run(capsys, ["locate", str(model), str(d2), "--json"]))
    (st,) = doc["stations"]
    rel = T2 @ np.linalg.inv(T1)                 # the model's measurement frame is S1's
    np.testing.assert_allclose(st["xyz_mm"], rel[:3, 3], atol=0.1)
    from scipy.spatial.transform import Rotation
    np.testing.assert_allclose(st["rpy_deg"], Rotation.from_matrix(rel[:3, :3]).as_euler("xyz", degrees=True),
                               atol=1e-3)
    assert st["rms_mm"] < 0.05
    ev = json.loads(_run(capsys, ["evaluate", str(model), str(d2), "--locate", "--json"]))
    assert ev["rms_mm"] < 0.05


def test_weak_data_with_priors_does_not_make_the_robot_worse(world, capsys):
    """Fit poses that barely move the wrist; held-out poses anywhere: with the priors of a description's tolerances
    and --free, the calibrated model predicts the held-out poses no worse than the nominal URDF."""
    tmp, truth, q, T1, data = world
    rng = np.random.default_rng(5)
    qf = rng.uniform(-2.5, 2.5, (25, 6))
    qf[:, 3:] = rng.uniform(-0.02, 0.02, (25, 3))         # wrist joints hardly move
    qt = rng.uniform(-2.5, 2.5, (30, 6))
    qa = np.vstack([qf, qt])
    p = _measure(truth, qa, np.eye(4), 3, noise=0.05)
    weak = _write(tmp / "weak.csv", qa, p, {"split": ["fit"] * 25 + ["test"] * 30})
    desc = tmp / "ur10.toml"
    desc.write_text(f'urdf = "{EX / "urdf" / "ur10_robot.urdf"}"\n[tolerances]\n'
                    + "".join(f'"{n}.a_mm" = 1.0\n"{n}.theta_offset_deg" = 0.05\n"{n}.alpha_deg" = 0.05\n'
                              f'"{n}.d_mm" = 1.0\n"{n}.beta_deg" = 0.05\n' for n in NAMES)
                    + '"tool.x_mm" = 1.0\n"tool.y_mm" = 1.0\n"tool.z_mm" = 1.0\n')
    doc = json.loads(_run(capsys, ["identify", str(weak), "--robot", str(desc), "--noise-mm", "0.05", "--json",
                                   "--free", "j*,tool.*", "--prior", "base.x_mm=0±0.01"]))
    # nominal: the URDF itself, evaluated on the same held-out rows (measurement frame = base link here)
    nominal_doc = {}
    from calib.rows import predict_rows
    from calib.model import MeasurementModel
    from calib.posecsv import read_pose_csv
    from calib.loading import load_robot
    robot = load_robot(desc)
    table = read_pose_csv(weak, robot=robot)
    m = MeasurementModel(robot)
    res = table.points_mm - predict_rows(m, m.nominal, table)
    test = table.split_mask("test")
    nominal_rms = float(np.sqrt(np.mean(np.sum(res[test] ** 2, axis=1))))
    assert nominal_rms > 1.0                                # the robot is off by a few mm
    assert doc["test_rms_mm"] < nominal_rms
    names = {p["name"]: p for p in doc["parameters"]}
    assert not names["base.z_mm"]["estimated"] and names["j3.a_mm"]["estimated"]


def test_total_station_rows_identify_with_their_own_noise_model(world, capsys):
    """hz_deg, v_deg, dist_mm rows (a total station at the measurement origin) instead of x, y, z."""
    tmp, truth, q, T1, data = world
    p = _measure(truth, q, T1, 7, noise=0.0)
    rng = np.random.default_rng(8)
    hz = np.mod(np.arctan2(-p[:, 1], p[:, 0]), 2 * np.pi) + rng.normal(0, 1e-6, len(p))
    v = np.arctan2(np.hypot(p[:, 0], p[:, 1]), p[:, 2]) + rng.normal(0, 1e-6, len(p))
    d = np.linalg.norm(p, axis=1) + rng.normal(0, 0.01, len(p))
    lines = [",".join(NAMES + ["hz_deg", "v_deg", "dist_mm", "split"])]
    for i in range(len(q)):
        lines.append(",".join([f"{x:.9f}" for x in np.degrees(q[i])] + [f"{np.degrees(hz[i]):.9f}",
                               f"{np.degrees(v[i]):.9f}", f"{d[i]:.5f}", "fit" if i < 40 else "test"]))
    f = tmp / "ts.csv"
    f.write_text("\n".join(lines) + "\n")
    doc = json.loads(_run(capsys, ["identify", str(f), "--robot", str(EX / "urdf" / "ur10_robot.urdf"), "--json",
                                   "--polar-noise", "0.2,0.01,0"]))
    assert doc["n_test"] == 20 and doc["test_rms_mm"] < 0.05
    # the noise model is the instrument's: a reduced chi-square near 1, not the default point noise's
    assert 0.5 < doc["reduced_chi2"] < 2.0


def _measure_points(urdf, q, pts_tip_mm, T, seed, noise):
    """Positions of points fixed on wrist_3_link (Pinocchio), in the instrument frame T."""
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    fid = model.getFrameId("wrist_3_link")
    out = []
    for row in q:
        qq = pin.neutral(model)
        for name, v in zip(NAMES, row):
            qq[model.joints[model.getJointId(name)].idx_q] = v
        pin.framesForwardKinematics(model, data, qq)
        M = data.oMf[fid]
        out.append([M.rotation @ (p / 1000.0) * 1000.0 + M.translation * 1000.0 for p in pts_tip_mm])
    p = np.array(out) @ T[:3, :3].T + T[:3, 3]                # (N, K, 3)
    return p + np.random.default_rng(seed).normal(0, noise, p.shape)


def test_three_reflectors_per_pose_are_fitted_jointly(world, capsys):
    """A laser tracker sees three reflectors on the flange (positions known to a few mm only): one identification
    finds the chain and all three reflectors; evaluate predicts each reflector of held-out poses."""
    tmp, truth, q, T1, data = world
    true_pts = np.array([[0.0, 0.0, 40.0], [60.0, 5.0, 30.0], [-20.0, 70.0, 25.0]])
    described = true_pts + [[2.0, -1.0, 3.0], [-3.0, 2.0, 1.0], [1.0, 3.0, -2.0]]
    desc = tmp / "ur10_3r.toml"
    desc.write_text(f'urdf = "{EX / "urdf" / "ur10_robot.urdf"}"\n[tool.points]\n'
                    + "".join(f"R{k + 1} = [{', '.join(str(v) for v in p)}]\n" for k, p in enumerate(described)))
    P = _measure_points(truth, q, true_pts, T1, 9, 0.01)
    lines = ["pose,target,split," + ",".join(NAMES) + ",x,y,z"]
    for i in range(len(q)):
        for k in range(3):
            if (i + k) % 7 == 0:
                continue                                     # a reflector not seen from the tracker
            lines.append(f"p{i},R{k + 1},{'fit' if i < 40 else 'test'}," + ",".join(f"{v:.9f}" for v in np.degrees(q[i]))
                         + "," + ",".join(f"{v:.6f}" for v in P[i, k]))
    f = tmp / "tracker.csv"
    f.write_text("\n".join(lines) + "\n")
    model = tmp / "m3.json"
    doc = json.loads(_run(capsys, ["identify", str(f), "--robot", str(desc), "--noise-mm", "0.01", "--json",
                                   "--out", str(model)]))
    assert doc["test_rms_mm"] < 0.05 and doc["test_max_mm"] < 0.1
    ev = json.loads(_run(capsys, ["evaluate", str(model), str(f), "--json"]))
    assert set(ev["by"]["target"]) == {"R1", "R2", "R3"}
    assert all(s["rms_mm"] < 0.05 for s in ev["by"]["target"].values())
    # the reflectors' relative positions are recovered (absolute ones trade with the last joint's parameters)
    from calib.compensate import load_model
    pts = load_model(model).model.robot.tool_points_mm
    got = np.array([pts["R2"] - pts["R1"], pts["R3"] - pts["R1"]])
    assert np.allclose(np.linalg.norm(got, axis=1), np.linalg.norm(true_pts[1:] - true_pts[0], axis=1), atol=0.05)


def test_two_stations_in_one_identification(world, capsys):
    """Rows from two instrument set-ups (column station) are fitted jointly: one chain, one base per set-up."""
    tmp, truth, q, T1, data = world
    T2 = np.eye(4)
    T2[:3, :3], T2[:3, 3] = rpy_matrix(0.02, 0.01, 2.0), [300.0, 1800.0, -120.0]
    qa, qb = q[:30], q[30:]
    pa, pb = _measure(truth, qa, T1, 12), _measure(truth, qb, T2, 13)
    split = (["fit"] * 20 + ["test"] * 10) * 2
    f = _write(tmp / "two.csv", np.vstack([qa, qb]), np.vstack([pa, pb]),
               {"station": ["S1"] * 30 + ["S2"] * 30, "split": split})
    model = tmp / "m_two.json"
    doc = json.loads(_run(capsys, ["identify", str(f), "--robot", str(EX / "urdf" / "ur10_robot.urdf"),
                                   "--noise-mm", "0.01", "--json", "--out", str(model)]))
    assert doc["test_rms_mm"] < 0.05
    ev = json.loads(_run(capsys, ["evaluate", str(model), str(f), "--json"]))
    assert set(ev["by"]["station"]) == {"S1", "S2"}
    assert all(s["rms_mm"] < 0.05 for s in ev["by"]["station"].values())


def test_orientation_rows_enter_the_identification(world, capsys):
    """A 6-D probe: rx/ry/rz_deg of the flange frame besides its position.  With few poses the orientation rows
    carry information the positions alone lack: the fit with them predicts held-out positions better."""
    tmp, truth, q, T1, data = world
    model = pin.buildModelFromUrdf(str(truth))
    dat = model.createData()
    fid = model.getFrameId("wrist_3_link")
    rng = np.random.default_rng(21)
    rows = []
    from scipy.spatial.transform import Rotation
    for i, row in enumerate(q[:24]):
        qq = pin.neutral(model)
        for name, v in zip(NAMES, row):
            qq[model.joints[model.getJointId(name)].idx_q] = v
        pin.framesForwardKinematics(model, dat, qq)
        M = dat.oMf[fid]
        p = T1[:3, :3] @ (M.translation * 1000.0) + T1[:3, 3] + rng.normal(0, 0.01, 3)
        R = Rotation.from_matrix(T1[:3, :3] @ M.rotation) * Rotation.from_rotvec(rng.normal(0, 1e-5, 3))
        rows.append((row, p, R.as_euler("xyz", degrees=True), "fit" if i < 14 else "test"))
    lines = [",".join(NAMES + ["x", "y", "z", "rx_deg", "ry_deg", "rz_deg", "split"])]
    for row, p, e, sp in rows:
        lines.append(",".join([f"{v:.9f}" for v in np.degrees(row)] + [f"{v:.6f}" for v in p]
                              + [f"{v:.9f}" for v in e] + [sp]))
    six = tmp / "six.csv"
    six.write_text("\n".join(lines) + "\n")
    three = tmp / "three.csv"
    three.write_text("\n".join(",".join(ln.split(",")[:9] + ln.split(",")[12:]) for ln in lines) + "\n")
    # the same free set on both (model selection could prune the two fits differently: this is about the rows)
    base = ["--robot", str(EX / "urdf" / "ur10_robot.urdf"), "--noise-mm", "0.01", "--json", "--select", "all"]
    with_o = json.loads(_run(capsys, ["identify", str(six), *base, "--orientation-noise-deg", "0.001"]))
    without = json.loads(_run(capsys, ["identify", str(three), *base]))
    assert with_o["n_fit"] == 14 and with_o["test_rms_mm"] < 0.1
    assert with_o["test_rms_mm"] < without["test_rms_mm"]


def test_evaluate_matches_stations_by_name(world, capsys):
    """A model identified from set-ups S1 and S2 evaluates a file holding only S2's rows in S2's frame (sorted
    order would take the file's first station for the model's first); a station the model lacks is one line."""
    tmp, truth, q, T1, data = world
    T2 = np.eye(4)
    T2[:3, :3], T2[:3, 3] = rpy_matrix(0.02, 0.01, 2.0), [300.0, 1800.0, -120.0]
    f = _write(tmp / "two_by_name.csv", np.vstack([q[:30], q[30:]]),
               np.vstack([_measure(truth, q[:30], T1, 12), _measure(truth, q[30:], T2, 13)]),
               {"station": ["S1"] * 30 + ["S2"] * 30})
    model = tmp / "m_by_name.json"
    _run(capsys, ["identify", str(f), "--robot", str(EX / "urdf" / "ur10_robot.urdf"), "--noise-mm", "0.01",
                  "--out", str(model)])
    assert json.loads(model.read_text())["stations"] == ["S1", "S2"]
    only2 = _write(tmp / "only_s2.csv", q[:20], _measure(truth, q[:20], T2, 14), {"station": ["S2"] * 20})
    ev = json.loads(_run(capsys, ["evaluate", str(model), str(only2), "--json"]))
    assert ev["rms_mm"] < 0.05 and set(ev["by"]["station"]) == {"S2"}
    s3 = _write(tmp / "s3.csv", q[:8], _measure(truth, q[:8], T2, 15), {"station": ["S2"] * 4 + ["S3"] * 4})
    assert main(["evaluate", str(model), str(s3)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"robocal: error: {s3}: line 6: column station: 'S3' is not a station of the model (its "
                   "stations: S1, S2); --locate re-stations it")
    # re-stationing takes a new set-up: S3's rows are located like any other station's
    ev = json.loads(_run(capsys, ["evaluate", str(model), str(s3), "--locate", "--json"]))
    assert ev["rms_mm"] < 0.05 and [s["station"] for s in ev["stations"]] == ["S2", "S3"]
