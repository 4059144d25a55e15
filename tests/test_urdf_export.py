"""``identify --out-urdf``: the calibrated URDF read back by Pinocchio (an independent implementation of URDF
kinematics) agrees with the calibrated model, and on data from an independently built "real robot" (a perturbed URDF
multiplied out as plain 4x4 products, tests/fakes/urdf_chain.py) it predicts held-out poses to the noise."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from calib.compensate import load_model
from calib.kinematics import Kinematics
from tests.dev_extra import require
from tests.fakes import thesis_puma as tp
from tests.fakes.urdf_chain import UrdfChain, instrument, perturbed, rpy_matrix

EX = Path(__file__).resolve().parents[1] / "examples"
pin = require("pinocchio", "pin")      # in the dev extra: missing there fails, it does not skip
UR10 = EX / "urdf" / "ur10_robot.urdf"
UR10_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
               "wrist_3_joint"]
MARKER_MM = np.array([40.0, -25.0, 90.0])        # a reflector on wrist_3_link, off every axis


def _side_base(side: dict) -> np.ndarray:
    b = side["base_link_in_measurement_frame"]
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rpy_matrix(*np.radians(b["rpy_deg"])), b["xyz_mm"]
    return T


def _run(capsys, argv):
    rc = main(argv)
    out = capsys.readouterr()
    assert rc == 0, out.err
    return out.out


class PinRobot:
    """The written URDF in Pinocchio: frames of links and joints in the chain's base link, mm."""

    def __init__(self, path, base_link):
        self.model = pin.buildModelFromUrdf(str(path))
        self.data = self.model.createData()
        self.base = base_link

    def run(self, values: dict[str, float]):
        q = pin.neutral(self.model)
        for name, v in values.items():
            q[self.model.joints[self.model.getJointId(name)].idx_q] = v
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        self._B = self.data.oMf[self.model.getFrameId(self.base)].inverse()

    def frame(self, link: str) -> np.ndarray:
        M = self._B * self.data.oMf[self.model.getFrameId(link)]
        return _se3(M)

    def joint(self, name: str) -> np.ndarray:
        return _se3(self._B * self.data.oMi[self.model.getJointId(name)])


def _se3(M) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = M.rotation, M.translation * 1000.0
    return T


def _axis_vectors(urdf_text: str, names) -> dict[str, np.ndarray]:
    import xml.etree.ElementTree as ET
    out = {}
    for j in ET.fromstring(urdf_text).findall("joint"):
        if j.get("type") in ("revolute", "continuous", "prismatic") and (names is None or j.get("name") in names):
            ax = j.find("axis")
            out[j.get("name")] = np.array([float(v) for v in (ax.get("xyz") if ax is not None else "1 0 0").split()])
    return out


def assert_round_trip(urdf: Path, side: dict, model_json: Path, q_rad: np.ndarray):
    """Pinocchio's placements of the written URDF (with the side file's base and tool points) against the calibrated
    model: every joint axis on the model's axis (direction and, revolute, line), every tool point on the model's."""
    im = load_model(model_json)
    robot = im.model.robot
    kin = Kinematics(robot)
    P = kin.P
    B = _side_base(side)
    pr = PinRobot(urdf, side["base_link"])
    in_file = _axis_vectors(urdf.read_text(), None)                   # a DH robot's file names its joints j1..jn
    names = list(robot.joint_names) if set(robot.joint_names) <= set(in_file) else [f"j{k}" for k in
                                                                                   range(1, robot.n + 1)]
    axes = _axis_vectors(urdf.read_text(), names)
    fp = kin.forward(q_rad, im.theta[:P])
    for i, q in enumerate(q_rad):
        pr.run({n: (v / 1000.0 if p else v) for n, v, p in zip(names, q, robot.prismatic)})
        for k, name in enumerate(names):
            J = B @ pr.joint(name)
            u = J[:3, :3] @ axes[name] / np.linalg.norm(axes[name])
            z, o = fp.frame_R[i, k, :, 2], fp.frame_t[i, k]
            assert np.linalg.norm(np.cross(u, z)) < 1e-9 and u @ z > 0, name
            if not robot.prismatic[k]:
                d = J[:3, 3] - o
                assert np.linalg.norm(d - (d @ z) * z) < 1e-6, name
        tip = B @ pr.frame(side["tip_link"])
        for name, tp_ in side["tool_points"].items():
            got = tip[:3, :3] @ tp_["xyz_mm"] + tip[:3, 3]
            want = kin.points(q_rad[i:i + 1], kin.params_with_tool(robot.tool_points_mm[name], im.theta[:P]))[0]
            np.testing.assert_allclose(got, want, atol=1e-6)


# -- UR10: an independent truth ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ur10_world(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ur10x")
    truth = UrdfChain(perturbed(UR10.read_text(), seed=5, mm=2.0, deg=0.3), "world", "wrist_3_link")
    rng = np.random.default_rng(17)
    q = rng.uniform(-2.8, 2.8, (70, 6))
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rpy_matrix(0.01, -0.02, 0.7), [1800.0, -400.0, 150.0]
    pts = instrument(truth.points(q, MARKER_MM)[:, 0], T, 0.01, seed=2)
    data = tmp / "ur10.csv"
    with data.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(UR10_JOINTS + ["x", "y", "z"])
        for qi, p in zip(q[:50], pts[:50]):
            w.writerow([f"{v:.10f}" for v in np.degrees(qi)] + [f"{v:.6f}" for v in p])
    desc = tmp / "ur10.toml"
    desc.write_text(f'urdf = "{UR10}"\n[tool.points]\nM = {MARKER_MM.tolist()}\n')
    return tmp, truth, q, T, data, desc


def test_ur10_export_predicts_the_independent_truth_and_round_trips_in_pinocchio(ur10_world, capsys):
    tmp, truth, q, T, data, desc = ur10_world
    out, model = tmp / "ur10_cal.urdf", tmp / "m.json"
    text = _run(capsys, ["identify", str(data), "--robot", str(desc), "--noise-mm", "0.01", "--out", str(model),
                         "--out-urdf", str(out)])
    assert "read back, its forward kinematics equals the calibrated model's on the 50 fitted poses" in text
    assert f"not in the URDF ({tmp / 'ur10_cal.side.json'}): world pose in the measurement frame; tool point M " \
           "on wrist_3_link" in text
    side = json.loads((tmp / "ur10_cal.side.json").read_text())
    assert side["check"]["max_mm"] < 1e-6 and side["check"]["n_poses"] == 50
    # every element but the six moving joints' origins is kept, in order
    import xml.etree.ElementTree as ET
    a, b = ET.parse(UR10).getroot(), ET.parse(out).getroot()
    assert [(e.tag, e.get("name")) for e in a] == [(e.tag, e.get("name")) for e in b]
    changed = [e.get("name") for e, f in zip(a, b) if ET.tostring(e) != ET.tostring(f)]
    assert set(changed) <= set(UR10_JOINTS) and len(changed) >= 5   # the first keeps its place (the base takes it)
    # Pinocchio reads the written file: joint axes and the reflector where the calibrated model has them
    held_out = q[50:]
    assert_round_trip(out, side, model, held_out)
    # ... and where the real robot has them: held-out poses to the noise (0.01 mm per coordinate)
    pr = PinRobot(out, side["base_link"])
    B = _side_base(side)
    marker = np.array(side["tool_points"]["M"]["xyz_mm"])
    err = []
    for qi, want in zip(held_out, instrument(truth.points(held_out, MARKER_MM)[:, 0], T, 0.0, seed=0)):
        pr.run(dict(zip(UR10_JOINTS, qi)))
        tip = B @ pr.frame("wrist_3_link")
        err.append(np.linalg.norm(tip[:3, :3] @ marker + tip[:3, 3] - want))
    assert np.sqrt(np.mean(np.square(err))) < 0.05 and max(err) < 0.1
    # the nominal URDF is millimetres off on the same poses: the export carries the calibration
    nominal = UrdfChain(UR10.read_text(), "world", "wrist_3_link")
    nom = instrument(nominal.points(held_out, MARKER_MM)[:, 0], T, 0.0, seed=0)
    want = instrument(truth.points(held_out, MARKER_MM)[:, 0], T, 0.0, seed=0)
    assert np.sqrt(np.mean(np.sum((nom - want) ** 2, axis=1))) > 1.0


# -- TIAGo: the real mocap set through its calibration description -------------------------------------------------
def test_tiago_export_round_trips_in_pinocchio(tmp_path, capsys):
    out, model = tmp_path / "tiago_cal.urdf", tmp_path / "t.json"
    doc = json.loads(_run(capsys, ["identify", str(EX / "tiago" / "qualysis_base_hand_calibration.csv"), "--robot",
                                   str(EX / "tiago" / "tiago_mocap.toml"), "--angle-unit", "rad", "--length-unit", "m",
                                   "--noise-mm", "1", "--out", str(model), "--out-urdf", str(out), "--json"]))
    assert doc["exported"]["urdf_check_max_mm"] < 1e-6 and doc["exported"]["urdf_check_poses"] == 34
    side = json.loads((tmp_path / "tiago_cal.side.json").read_text())
    assert side["base_link"] == "base_footprint" and side["tip_link"] == "arm_7_link"
    robot = load_model(model).model.robot
    rng = np.random.default_rng(3)
    lim = np.where(robot.prismatic[:, None], robot.limits_rad, np.clip(robot.limits_rad, -2.5, 2.5))
    assert_round_trip(out, side, model, rng.uniform(lim[:, 0], lim[:, 1], (20, robot.n)))
    # the head and everything off the arm is untouched
    import xml.etree.ElementTree as ET
    a = {e.get("name"): ET.tostring(e) for e in ET.parse(EX / "urdf" / "tiago_no_hand.urdf").getroot()}
    b = {e.get("name"): ET.tostring(e) for e in ET.parse(out).getroot()}
    assert sorted(k for k in a if a[k] != b.get(k)) == sorted(robot.joint_names)


# -- a DH description: a URDF made from its frames, and the controller's delta table -------------------------------
@pytest.fixture(scope="module")
def puma_world(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pumax")
    arm = tp.ThesisPuma.from_toml(Path(__file__).resolve().parents[1] / "calib" / "data" / "puma560.toml")
    arm.a_mm = arm.a_mm + np.array([0.0, 0.8, -0.6, 0.0, 0.0, 0.0])
    arm.d_mm = arm.d_mm + np.array([0.0, 0.5, 0.0, -0.7, 0.0, 0.0])
    arm.alpha = arm.alpha + np.radians([0.0, 0.1, -0.15, 0.1, 0.0, 0.0])
    arm.theta_offset = np.radians([0.0, 0.2, -0.1, 0.15, -0.2, 0.0])
    arm.base = tp.base_matrix((1500.0, 200.0, -300.0), yaw=0.4)
    arm.tool_xyz_t = (-30.0, 20.0, -120.0)                  # the tool point at (30, -20, 120) in frame 6
    rng = np.random.default_rng(4)
    q = rng.uniform(-2.5, 2.5, (80, 6))
    pts, _ = tp.true_points(arm, q)
    pts = pts + rng.normal(0, 0.01, pts.shape)
    data = tmp / "puma.csv"
    with data.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow([f"q{k}" for k in range(1, 7)] + ["x", "y", "z"])
        for qi, p in zip(q[:60], pts[:60]):
            w.writerow([f"{v:.10f}" for v in np.degrees(qi)] + [f"{v:.6f}" for v in p])
    return tmp, arm, q, data


def test_dh_robot_gets_a_urdf_and_a_delta_table(puma_world, capsys):
    tmp, arm, q, data = puma_world
    out, model, deltas = tmp / "puma_cal.urdf", tmp / "p.json", tmp / "deltas.csv"
    text = _run(capsys, ["identify", str(data), "--noise-mm", "0.01", "--out", str(model), "--out-urdf", str(out),
                         "--out-dh-deltas", str(deltas), "--effect", "transmission_error:4:0.9"])
    assert "(written from the model's frames); read back" in text
    assert "transmission_error j4" in text.split("not in the URDF")[1]
    side = json.loads((tmp / "puma_cal.side.json").read_text())
    assert side["tip_link"] == "flange"
    assert [e["label"] for e in side["effects"]] == ["transmission_error j4 (order 0.9/rad)"]
    assert_round_trip(out, side, model, q[60:])
    # Pinocchio's flange with the side file's base and tool point lands on the independent arm's tool point
    pr = PinRobot(out, "base_link")
    B = _side_base(side)
    tool = np.array(next(iter(side["tool_points"].values()))["xyz_mm"])
    truth, _ = tp.true_points(arm, q[60:])
    got = []
    for qi in q[60:]:
        pr.run({f"j{k + 1}": v for k, v in enumerate(qi)})
        F = B @ pr.frame("flange")
        got.append(F[:3, :3] @ tool + F[:3, 3])
    assert np.sqrt(np.mean(np.sum((np.array(got) - truth) ** 2, axis=1))) < 0.05
    # the delta table: one row per joint, held parameters named and without a made-up sigma
    rows = list(csv.DictReader(line for line in deltas.read_text().splitlines() if not line.startswith("#")))
    assert [r["joint"] for r in rows] == [str(k) for k in range(1, 7)]
    for r in rows:
        for col in ("dtheta_deg", "dd_mm", "da_mm", "dalpha_deg", "dbeta_deg"):
            if col.split("_")[0][1:] in r["held"].split():
                assert float(r[col]) == 0.0 and float(r[f"sigma_{col}"]) == 0.0
    # link 3 (upper arm to forearm, Fig 3.5's a2) is seen directly by these poses: its delta is the truth's
    a3 = rows[2]
    assert abs(float(a3["da_mm"]) - (-0.6)) < 4 * float(a3["sigma_da_mm"]) + 0.02


def test_dh_deltas_of_a_urdf_description_is_one_line(ur10_world, capsys):
    tmp, truth, q, T, data, desc = ur10_world
    rc = main(["identify", str(data), "--robot", str(desc), "--noise-mm", "0.01", "--out-dh-deltas",
               str(tmp / "d.csv")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.count("\n") == 0 and "is a URDF description" in err and "--out-urdf" in err


def test_reprocess_writes_the_sessions_calibrated_urdf(tmp_path, capsys):
    """The shipped demo session (a Puma 560 DH description): reprocess --out-urdf writes the pose set's identified
    robot, read back and checked on the set's own poses; Pinocchio agrees with the model on random configurations."""
    out, res_json = tmp_path / "demo.urdf", tmp_path / "res.json"
    text = _run(capsys, ["reprocess", str(EX / "demo-session.db"), "--out-urdf", str(out), "--json", str(res_json),
                         "--out-dh-deltas", str(tmp_path / "d.csv")])
    assert f"DH deltas written: {tmp_path / 'd.csv'}" in text
    assert (tmp_path / "d.csv").read_text().count("\n") == 8           # comment, header, six joints
    assert "read back, its forward kinematics equals the calibrated model's on the 48 fitted poses" in text
    line = next(ln for ln in text.splitlines() if ln.startswith("not in the URDF"))
    assert "transmission_error j4" in line and "cross_coupling j4->j6" in line and "motor coupling matrix" in line
    side = json.loads((tmp_path / "demo.side.json").read_text())
    res = json.loads(res_json.read_text())
    model = tmp_path / "m.json"
    model.write_text(json.dumps(res["robot"]))
    rng = np.random.default_rng(9)
    assert_round_trip(out, side, model, rng.uniform(-2.5, 2.5, (10, 6)))


def test_a_reading_convention_goes_to_the_side_file(ur10_world, tmp_path, capsys):
    """An encoder whose zero is not the joint's (the elbow read 5 deg off): the URDF holds joints, the side file the
    readings' map, and the one line says so."""
    tmp, truth, q, T, data, desc = ur10_world
    lines = data.read_text().splitlines()
    shifted = [lines[0]] + [",".join(f"{float(v) - 5.0:.10f}" if k == 2 else v for k, v in enumerate(ln.split(",")))
                            for ln in lines[1:]]
    (tmp_path / "r.csv").write_text("\n".join(shifted) + "\n")
    conv = tmp_path / "ur10_readings.toml"
    conv.write_text(desc.read_text() + "[readings]\nnames = " + json.dumps(UR10_JOINTS) + "\n[readings.joints]\n"
                    "elbow_joint = { elbow_joint = 1.0, offset_deg = 5.0 }\n")
    out = tmp_path / "cal.urdf"
    text = _run(capsys, ["identify", str(tmp_path / "r.csv"), "--robot", str(conv), "--noise-mm", "0.01",
                         "--out-urdf", str(out), "--out", str(tmp_path / "m.json")])
    line = next(ln for ln in text.splitlines() if "not in the URDF" in ln)
    assert "reading conventions (joint = matrix @ reading + offset)" in line
    side = json.loads((tmp_path / "cal.side.json").read_text())
    assert side["readings"]["offset"] == pytest.approx([0, 0, 5.0, 0, 0, 0])
    assert_round_trip(out, side, tmp_path / "m.json", q[50:55])
