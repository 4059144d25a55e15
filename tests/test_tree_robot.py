"""Branched robots (issue 23.1-2): two arms on one torso, a coupled torso joint, a lifting column whose stages mimic a
leader on a side branch -- against an independent generator (plain 4x4 products, tests/fakes/tree_robot.py) and
Pinocchio's reading of the same URDF."""
from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from calib.errors import RobocalError
from calib.effects.joint_compliance import JointCompliance
from calib.kinematics import Kinematics
from calib.model import MeasurementModel
from calib.robot import parse_robot, robot_to_toml
from calib.loading import load_robot
from calib.targets import TargetContext, with_targets
from tests.dev_extra import require
from tests.fakes import tree_robot as tr
from tests.fakes.oracle.chain import numeric_jacobian

POINTS = {"L": ("hand_left_link", [0.0, 0.0, 30.0]), "R": ("hand_right_link", [10.0, 0.0, 30.0])}
COUPLED = "[joints.coupled]\ntorso_3_joint = { torso_1_joint = -1.0, torso_2_joint = -1.0 }\n"


def _description(tmp_path, tree, points=POINTS, extra=COUPLED, name="robot") -> str:
    (tmp_path / f"{name}.urdf").write_text(tr.to_urdf(tree))
    lines = [f'urdf = "{name}.urdf"', 'base_link = "base_link"', "[tool.points]"]
    lines += [f'{k} = {{ link = "{link}", xyz_mm = [{", ".join(map(str, xyz))}] }}' for k, (link, xyz) in points.items()]
    path = tmp_path / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n" + extra)
    return str(path)


def _values(robot, tree, n, seed):
    vals = tr.random_values(tree, n, seed, names=list(robot.reading_names))
    for v in vals:
        v["torso_3_joint"] = -(v["torso_1_joint"] + v["torso_2_joint"])
    return vals


def _point(kin, robot, name, q):
    return kin.forward(q, kin.params_with_tool(robot.tool_points_mm[name]), robot.point_frame(name)).point


def test_two_arms_on_one_torso_match_plain_products(tmp_path):
    tree = tr.two_arm_torso(0)
    robot = load_robot(_description(tmp_path, tree))
    assert robot.is_tree
    # the shared torso is one set of parameters; the coupled joint is not a reading
    assert robot.joint_names.count("torso_2_joint") == 1
    assert "torso_3_joint" not in robot.reading_names and len(robot.reading_names) == 16
    kin = Kinematics(robot)
    for v in _values(robot, tree, 20, 1):
        q = robot.joints_from_readings(np.array([[v[k] for k in robot.reading_names]]))
        for name, (link, xyz) in POINTS.items():
            np.testing.assert_allclose(_point(kin, robot, name, q)[0], tr.point_mm(tree, v, link, xyz), atol=1e-6)


def test_tree_matches_pinocchio(tmp_path):
    pin = require("pinocchio", "pin")
    tree = tr.two_arm_torso(3)
    robot = load_robot(_description(tmp_path, tree))
    model = pin.buildModelFromUrdf(str(tmp_path / "robot.urdf"))
    data = model.createData()
    kin = Kinematics(robot)
    for v in _values(robot, tree, 10, 4):
        qp = pin.neutral(model)
        for name, val in v.items():
            qp[model.joints[model.getJointId(name)].idx_q] = val
        pin.framesForwardKinematics(model, data, qp)
        q = robot.joints_from_readings(np.array([[v[k] for k in robot.reading_names]]))
        for name, (link, xyz) in POINTS.items():
            want = data.oMf[model.getFrameId(link)].act(np.array(xyz) / 1000.0) * 1000.0
            np.testing.assert_allclose(_point(kin, robot, name, q)[0], want, atol=1e-6)


def test_mimic_stages_follow_a_leader_on_a_side_branch(tmp_path):
    tree = tr.lifting_column(1)
    path = _description(tmp_path, tree, {"tip": ("arm_6_link", [0.0, 0.0, 50.0])}, extra="", name="column")
    robot = load_robot(path)
    assert "column_drive_joint" in robot.reading_names                  # the leader's value is a data column
    assert "stage_1_joint" not in robot.reading_names
    kin = Kinematics(robot)
    for v in tr.random_values(tree, 10, 2):
        r = np.array([[v[k] * (1000.0 if k == "column_drive_joint" else 1.0) for k in robot.reading_names]])
        got = _point(kin, robot, "tip", robot.joints_from_readings(r))[0]
        np.testing.assert_allclose(got, tr.point_mm(tree, v, "arm_6_link", [0, 0, 50]), atol=1e-6)


def test_whole_tree_gravity_torques(tmp_path):
    """A torso joint carries both arms and the head (held at zero: not on the robot's tree, its mass lumped where
    it hangs); every joint's torque against a plain sum over the generator's links."""
    tree = tr.two_arm_torso(0)
    robot = load_robot(_description(tmp_path, tree))
    model = MeasurementModel(robot)
    vals = _values(robot, tree, 5, 9)
    q = robot.joints_from_readings(np.array([[v[k] for k in robot.reading_names] for v in vals]))
    ctx = model.context(len(q))
    loads = model.loads(model.kin.forward(q), ctx)
    # the measurement frame is the base link here (no [base] table): gravity is the generator's
    for i, v in enumerate(vals):
        want = tr.gravity_torques(tree, v)
        for k, name in enumerate(robot.joint_names):
            if name in want and robot.variable_of[k] == k:
                assert loads.joint_torque_nm[i, k] == pytest.approx(want[name], abs=1e-9 + 1e-9 * abs(want[name]))


def test_tree_jacobian_matches_finite_differences(tmp_path):
    """The identification Jacobian of a tree (rows on both arms, a compliant torso joint whose torque carries both
    arms, the torque derivative on) against central differences of the model itself."""
    tree = tr.two_arm_torso(0)
    robot = load_robot(_description(tmp_path, tree))
    robot, targets = with_targets(robot, ["L", "R"])
    k2 = robot.joint_names.index("torso_2_joint") + 1
    model = MeasurementModel(robot, targets + [JointCompliance(k2, 3000.0)])   # 0.04 rad under 120 N m
    vals = _values(robot, tree, 4, 5)
    q = robot.joints_from_readings(np.array([[v[k] for k in robot.reading_names] for v in vals]))
    q = np.repeat(q, 2, axis=0)
    ctx = TargetContext(len(q), robot.n, target=np.tile([0, 1], 4))
    theta = model.nominal
    ev = model.evaluate(q, ctx, theta, jacobian=True, torque_derivative=True)
    steps = np.array([1e-6 if name.endswith("_mm") else 1e-7 for name in model.names])
    num = numeric_jacobian(lambda th: model.points(q, ctx, th), theta, steps)
    np.testing.assert_allclose(ev.jacobian, num, atol=2e-5 * np.abs(num).max())


def _write_data(path, tree, robot, n, seed, noise_mm=0.05):
    rng = np.random.default_rng(seed)
    names = list(robot.reading_names)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["pose", "target"] + names + ["x", "y", "z", "split"])
        for i, v in enumerate(_values(robot, tree, n, seed)):
            for t, (link, xyz) in POINTS.items():
                p = tr.point_mm(tree, v, link, xyz) + rng.normal(0, noise_mm, 3)
                w.writerow([f"p{i}", t] + [f"{np.degrees(v[k]):.9f}" for k in names] + [f"{x:.6f}" for x in p]
                           + ["test" if i % 4 == 0 else "fit"])


def test_one_fit_of_both_arms_and_the_shared_torso(tmp_path):
    """Data of the perturbed generator (the 'real' robot), two hands a pose: one identification of the tree reaches
    the noise floor on held-out poses and gives one torso."""
    nominal = tr.two_arm_torso(0)
    real = tr.perturbed(nominal, 11)
    desc = _description(tmp_path, nominal)
    robot = load_robot(desc)
    data = tmp_path / "poses.csv"
    _write_data(data, real, robot, 80, 12)
    out = subprocess.run([sys.executable, "-m", "app.cli", "identify", str(data), "--robot", desc, "--noise-mm", "0.05",
                          "--json", "--out-urdf", str(tmp_path / "calibrated.urdf")], capture_output=True, text=True,
                         cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    names = [p["name"] for p in doc["parameters"]]
    assert sum(n.startswith("base.") for n in names) == 6                 # one base, not one per arm
    torso = robot.joint_names.index("torso_2_joint") + 1
    assert sum(n.startswith(f"j{torso}.") for n in names) == 5            # one torso_2 link, fitted once
    floor = 0.05 * np.sqrt(3)                                             # per point, 3-D
    assert doc["test_rms_mm"] < 1.25 * floor
    # the nominal description is millimetres off: the fit did the work
    model = MeasurementModel(robot)
    rows = list(csv.DictReader(open(data)))
    q = robot.joints_from_readings(np.radians([[float(r[k]) for k in robot.reading_names] for r in rows]))
    frames = np.array([robot.point_frame(r["target"]) for r in rows])
    p_nom = np.array([Kinematics(robot).forward(q[i:i + 1], model.kin.params_with_tool(
        robot.tool_points_mm[r["target"]]), frames[i]).point[0] for i, r in enumerate(rows)])
    meas = np.array([[float(r[c]) for c in "xyz"] for r in rows])
    assert np.sqrt(np.mean(np.sum((p_nom - meas) ** 2, axis=1))) > 5 * doc["test_rms_mm"]
    # the calibrated URDF, read by Pinocchio and placed by the side file's base, predicts the test rows as well
    pin = require("pinocchio", "pin")
    side = json.loads((tmp_path / "calibrated.side.json").read_text())
    base = side["base_link_in_measurement_frame"]
    from tests.fakes.tree_robot import hom, rpy_matrix
    B = hom(rpy_matrix(*np.radians(base["rpy_deg"])), np.array(base["xyz_mm"]))
    pm = pin.buildModelFromUrdf(str(tmp_path / "calibrated.urdf"))
    pd = pm.createData()
    err = []
    for r in rows:
        if r["split"] != "test":
            continue
        qp = pin.neutral(pm)
        vals = {k: np.radians(float(r[k])) for k in robot.reading_names}
        vals["torso_3_joint"] = -(vals["torso_1_joint"] + vals["torso_2_joint"])
        for name, v in vals.items():
            qp[pm.joints[pm.getJointId(name)].idx_q] = v
        pin.framesForwardKinematics(pm, pd, qp)
        tp = side["tool_points"][r["target"]]
        p = pd.oMf[pm.getFrameId(tp["link"])].act(np.array(tp["xyz_mm"]) / 1000.0) * 1000.0
        err.append(B[:3, :3] @ p + B[:3, 3] - np.array([float(r[c]) for c in "xyz"]))
    rms = float(np.sqrt(np.mean(np.sum(np.square(err), axis=1))))
    assert rms == pytest.approx(doc["test_rms_mm"], rel=1e-6)


def test_identified_tree_round_trips_through_its_description(tmp_path):
    tree = tr.two_arm_torso(0)
    robot = load_robot(_description(tmp_path, tree))
    again = parse_robot(robot_to_toml(robot), "written")
    assert again.joint_names == robot.joint_names
    np.testing.assert_array_equal(again.parent_frame, robot.parent_frame)
    np.testing.assert_array_equal(again.variable_of, robot.variable_of)
    assert all(again.point_frame(k) == robot.point_frame(k) for k in POINTS)
    q = robot.joints_from_readings(np.radians(np.full((1, robot.n_readings), 20.0)))
    for name in POINTS:
        np.testing.assert_allclose(_point(Kinematics(again), again, name, q), _point(Kinematics(robot), robot, name, q),
                                   atol=1e-9)


@pytest.mark.parametrize("extra,match", [
    ("[joints.coupled]\ntorso_3_joint = { torso_3_joint = 1.0 }\n", "coupled to itself"),
    ("[joints.coupled]\ntorso_3_joint = { nope_joint = 1.0 }\n", "nope_joint: is not a moving joint"),
    ("[joints.coupled]\ntorso_3_joint = { torso_2_joint = 1.0 }\ntorso_2_joint = { torso_3_joint = 1.0 }\n",
     "form a cycle"),
    ("[joints.coupled]\ntorso_3_joint = { torso_2_joint = 1.0, offset_mm = 1.0 }\n", "revolute: use offset_deg"),
])
def test_bad_coupling_is_one_line(tmp_path, extra, match):
    with pytest.raises(RobocalError, match=match):
        load_robot(_description(tmp_path, tr.two_arm_torso(0), extra=extra))


def test_point_on_an_unknown_link_is_one_line(tmp_path):
    desc = _description(tmp_path, tr.two_arm_torso(0), {"L": ("no_such_link", [0, 0, 0])}, extra="")
    out = subprocess.run([sys.executable, "-m", "app.cli", "fk", "--robot", desc] + ["0"] * 16, capture_output=True,
                         text=True)
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "tool.points.L.link" in out.stderr and "no_such_link" in out.stderr


def test_fk_prints_every_point(tmp_path):
    tree = tr.two_arm_torso(0)
    desc = _description(tmp_path, tree)
    robot = load_robot(desc)
    out = subprocess.run([sys.executable, "-m", "app.cli", "fk", "--robot", desc, "--json"] + ["10"] * 16,
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    v = {k: np.radians(10.0) for k in robot.reading_names}
    v["torso_3_joint"] = -(v["torso_1_joint"] + v["torso_2_joint"])
    for name, (link, xyz) in POINTS.items():
        got = [doc["points"][name][c] for c in ("x_mm", "y_mm", "z_mm")]
        np.testing.assert_allclose(got, tr.point_mm(tree, v, link, xyz), atol=1e-5)


def test_contradictory_shared_joint_in_one_pose_is_one_line(tmp_path):
    tree = tr.two_arm_torso(0)
    desc = _description(tmp_path, tree)
    robot = load_robot(desc)
    data = tmp_path / "poses.csv"
    _write_data(data, tree, robot, 12, 1)
    lines = data.read_text().splitlines()
    cells = lines[4].split(",")                    # pose p1, target R: its torso_1_joint reading moved by 1 deg
    cells[2] = f"{float(cells[2]) + 1.0:.9f}"
    lines[4] = ",".join(cells)
    data.write_text("\n".join(lines) + "\n")
    out = subprocess.run([sys.executable, "-m", "app.cli", "identify", str(data), "--robot", desc],
                         capture_output=True, text=True)
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1 and "line 5" in out.stderr and "torso_1_joint" in out.stderr


def test_rows_without_a_target_on_a_tree_are_one_line(tmp_path):
    """Points on two arms and rows that do not say which they measure: refused, not fitted to the first point."""
    tree = tr.two_arm_torso(0)
    desc = _description(tmp_path, tree)
    robot = load_robot(desc)
    data = tmp_path / "poses.csv"
    _write_data(data, tree, robot, 6, 1)
    rows = list(csv.reader(open(data)))
    k = rows[0].index("target")
    data.write_text("\n".join(",".join(r[:k] + r[k + 1:]) for r in rows) + "\n")
    out = subprocess.run([sys.executable, "-m", "app.cli", "identify", str(data), "--robot", desc],
                         capture_output=True, text=True)
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and "a target column" in out.stderr


def test_two_points_a_pose_count_as_equations(tmp_path):
    """25 poses with two hands each give 150 equations: enough for the tree's ~84 parameters (the data check counted
    poses, three equations each, and refused)."""
    tree = tr.two_arm_torso(0)
    desc = _description(tmp_path, tree)
    robot = load_robot(desc)
    data = tmp_path / "poses.csv"
    _write_data(data, tr.perturbed(tree, 2), robot, 25, 3)
    out = subprocess.run([sys.executable, "-m", "app.cli", "identify", str(data), "--robot", desc, "--noise-mm",
                          "0.05", "--select", "all"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
