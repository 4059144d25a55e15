"""URDF import: the chain robocal builds from a URDF against Pinocchio's own reading of the same file."""
import numpy as np
import pytest

from tests.dev_extra import require

from calib.errors import RobocalError
from calib.kinematics import Kinematics
from calib.urdf import robot_from_urdf
from calib.loading import load_robot
from calib.units import DEG
from tests.fakes.oracle.chain import rot_x, rot_y, rot_z, trans

URDFS = str(__import__("pathlib").Path(__file__).resolve().parents[1] / "examples" / "urdf")
CASES = [("ur10_robot.urdf", None, None), ("tx40_mdh_modified.urdf", None, None),
         ("tiago_no_hand.urdf", "base_footprint", "arm_7_link"), ("tiago_no_hand.urdf", "torso_lift_link", "head_2_link")]


def _pin_tip(path, base, tip, names, q_by_name):
    pin = require("pinocchio", "pin")
    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    q = pin.neutral(model)
    for name, v in q_by_name.items():
        jid = model.getJointId(name)
        q[model.joints[jid].idx_q] = v
    pin.framesForwardKinematics(model, data, q)
    Tb = data.oMf[model.getFrameId(base)] if base else pin.SE3.Identity()
    Tt = data.oMf[model.getFrameId(tip)]
    return (Tb.inverse() * Tt).translation * 1000.0


def _tip_in_base(robot, readings):
    """Tip point (mm) in the URDF base link: the chain with the base pose set to frame 0 in the base link."""
    from calib.angles import rpy_from_matrix
    kin = Kinematics(robot)
    p = kin.nominal.copy()
    F0 = robot.frame0_in_base
    p[[kin.index[f"base.{k}"] for k in ("x_mm", "y_mm", "z_mm")]] = F0[:3, 3]
    p[[kin.index[f"base.{k}"] for k in ("roll_rad", "pitch_rad", "yaw_rad")]] = rpy_from_matrix(F0[:3, :3])
    return kin.points(robot.joints_from_readings(readings), p)


@pytest.mark.parametrize("fname,base,tip", CASES)
def test_chain_matches_pinocchio_on_random_configurations(fname, base, tip):
    path = f"{URDFS}/{fname}"
    robot = robot_from_urdf(path, base, tip)
    rng = np.random.default_rng(7)
    lo = np.clip(robot.limits_rad[:, 0], -np.pi, None)
    hi = np.clip(robot.limits_rad[:, 1], None, np.pi)
    for _ in range(20):
        r = rng.uniform(lo, hi)          # readings = joints here (no mimic joint in these chains)
        got = _tip_in_base(robot, r[None])[0]
        si = {name: v / 1000.0 if pris else v for name, v, pris in zip(robot.joint_names, r, robot.prismatic)}
        want = _pin_tip(path, base, tip or robot.name.split("-> ")[1].rstrip(")"), robot.joint_names, si)
        np.testing.assert_allclose(got, want, atol=1e-6)


def test_joint_names_and_kinds_are_kept():
    robot = robot_from_urdf(f"{URDFS}/tiago_no_hand.urdf", tip_link="arm_7_link")
    assert robot.joint_names == ("torso_lift_joint",) + tuple(f"arm_{k}_joint" for k in range(1, 8))
    assert robot.prismatic.tolist() == [True] + [False] * 7
    np.testing.assert_allclose(robot.limits_rad[0], [0.0, 350.0])
    # torso lift and arm_1 are both vertical: the Hayati beta carries that link
    assert robot.hayati[0]
    assert "arm_1_joint" in robot.param_meaning["j1.a_mm"]


def test_masses_are_the_urdf_inertials():
    path = f"{URDFS}/ur10_robot.urdf"
    robot = robot_from_urdf(path)
    # ur_description UR10 link masses (shoulder 7.778 ... wrist_1, wrist_2 1.96)
    np.testing.assert_allclose(robot.mass_kg[:5], [7.778, 12.93, 3.87, 1.96, 1.96], atol=1e-9)
    # wrist_3 carries a fixed camera mount: Pinocchio folds the same bodies onto the joint
    pin = require("pinocchio", "pin")
    model = pin.buildModelFromUrdf(path)
    want = [model.inertias[model.getJointId(n)].mass for n in robot.joint_names]
    np.testing.assert_allclose(robot.mass_kg, want, atol=1e-9)


def test_mass_centre_is_where_the_urdf_puts_it():
    """The centre of mass of the last link, carried through the chain, lands where the URDF frames put it."""
    path = f"{URDFS}/ur10_robot.urdf"
    robot = robot_from_urdf(path)
    rng = np.random.default_rng(3)
    r = rng.uniform(-2, 2, 6)
    kin = Kinematics(robot)
    fp = kin.forward(robot.joints_from_readings(r[None]))
    com_world = fp.frame_R[0, -1] @ robot.com_mm[-1] + fp.frame_t[0, -1]
    pin = require("pinocchio", "pin")
    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    q = pin.neutral(model)
    for name, v in zip(robot.joint_names, r):
        q[model.joints[model.getJointId(name)].idx_q] = v
    pin.forwardKinematics(model, data, q)
    jid = model.getJointId(robot.joint_names[-1])
    want = data.oMi[jid].act(model.inertias[jid].lever) * 1000.0
    # frame 0 of the chain is the measurement frame's base pose (the base link here)
    np.testing.assert_allclose(com_world, want, atol=1e-6)


MIMIC = """<robot name="m">
  <link name="b"/><link name="l1"/><link name="l2"/><link name="l3"/>
  <joint name="j1" type="revolute"><parent link="b"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.3 0 0.1" rpy="0.2 0 0"/>
    <axis xyz="0 1 0"/><mimic joint="j1" multiplier="-2" offset="0.1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j3" type="prismatic"><parent link="l2"/><child link="l3"/><origin xyz="0.2 0.1 0" rpy="0 0.3 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.5" effort="1" velocity="1"/></joint>
</robot>"""


def test_mimic_joint_is_driven_by_the_joint_it_follows(tmp_path):
    f = tmp_path / "m.urdf"
    f.write_text(MIMIC)
    robot = robot_from_urdf(f)
    assert robot.reading_names == ("j1", "j3") and robot.n == 3
    r = np.array([[0.4, 120.0]])
    q1 = 0.4
    q2 = -2 * q1 + 0.1
    # independent: plain homogeneous products (the tests' oracle)
    T = rot_z(q1) @ trans(300, 0, 100) @ rot_x(0.2) @ rot_y(q2) @ trans(200, 100, 0) @ rot_y(0.3) @ trans(120, 0, 0)
    np.testing.assert_allclose(_tip_in_base(robot, r)[0], T[:3, 3], atol=1e-9)


@pytest.mark.parametrize("text,match", [
    (MIMIC.replace('<joint name="j3" type="prismatic"><parent link="l2"/><child link="l3"/>',
                   '<joint name="j3" type="prismatic"><parent link="l2"/><child link="l1"/>'), "closed loop"),
    (MIMIC.replace('<child link="l3"/>', '<child link="l9"/>'), "link 'l9' is not defined"),
])
def test_bad_urdf_is_one_line(tmp_path, text, match):
    f = tmp_path / "bad.urdf"
    f.write_text(text)
    with pytest.raises(RobocalError, match=match) as e:
        robot_from_urdf(f)
    assert str(f) in str(e.value) and "line" in str(e.value)


def test_unknown_link_lists_the_links():
    with pytest.raises(RobocalError, match="tip link 'nowhere' is not in the URDF .*arm_7_link"):
        robot_from_urdf(f"{URDFS}/tiago_no_hand.urdf", tip_link="nowhere")


def test_several_leaves_are_listed():
    with pytest.raises(RobocalError, match="moving leaves .*head_2_link.*arm_7_link.*--tip-link"):
        robot_from_urdf(f"{URDFS}/tiago_no_hand.urdf")


def test_fk_command_prints_the_tip_in_the_base_link(capsys):
    from app.cli import main
    path = f"{URDFS}/tiago_no_hand.urdf"
    rc = main(["fk", "--robot", path, "--tip-link", "arm_7_link", "--json", "100", "10", "20", "30", "40", "50",
               "60", "70"])
    assert rc == 0
    import json
    got = json.loads(capsys.readouterr().out)
    r = [0.1] + [v * DEG for v in (10, 20, 30, 40, 50, 60, 70)]
    robot = load_robot(path, tip_link="arm_7_link")
    want = _pin_tip(path, None, "arm_7_link", None, dict(zip(robot.joint_names, r)))
    np.testing.assert_allclose([got["x_mm"], got["y_mm"], got["z_mm"]], want, atol=1e-5)


@pytest.mark.parametrize("case", ["loop", "tip", "column", "target", "split", "reading"])
def test_bad_input_is_one_line_exit_2(tmp_path, capsys, case):
    """The issue's list of bad input, through the command line: one line naming the file and the place, exit 2."""
    from app.cli import main
    ur10 = f"{URDFS}/ur10_robot.urdf"
    names = "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint"
    desc = tmp_path / "d.toml"
    desc.write_text(f'urdf = "{ur10}"\n[tool.points]\nR1 = [0, 0, 0]\n')
    data = tmp_path / "data.csv"
    if case == "loop":
        bad = tmp_path / "loop.urdf"
        bad.write_text(MIMIC.replace('<child link="l3"/>', '<child link="l1"/>'))
        argv, where = ["fk", "--robot", str(bad), "0", "0"], "loop.urdf: line"
    elif case == "tip":
        argv, where = ["fk", "--robot", ur10, "--tip-link", "hand"] + ["0"] * 6, "tip link 'hand'"
    elif case == "reading":
        desc.write_text(f'urdf = "{ur10}"\n[readings]\nnames = ["J1"]\n[readings.joints]\nelbow_joint = {{ J7 = 1 }}\n')
        argv, where = ["fk", "--robot", str(desc), "0"], "d.toml: readings.joints.elbow_joint.J7"
    else:
        extra = {"column": ("arm_1_joint", "0", "column arm_1_joint is not a joint"),
                 "target": ("target", "R9", "line 2: column target: 'R9' names no tool point"),
                 "split": ("split", "train", "line 2: column split: 'train' must be fit or test")}[case]
        data.write_text(f"{names},x,y,z,{extra[0]}\n0,0,0,0,0,0,1,2,3,{extra[1]}\n")
        argv, where = ["identify", str(data), "--robot", str(desc)], f"data.csv: {extra[2]}" if case != "column" \
            else "data.csv: line 1: column arm_1_joint is not a joint"
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and where in err, err
