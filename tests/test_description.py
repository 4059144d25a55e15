"""The calibration description wrapping a URDF: tool points, base, masses, drives, tolerances, reading conventions."""
from pathlib import Path

import numpy as np
import pytest

from calib.errors import RobocalError
from calib.urdf import robot_from_urdf
from calib.loading import load_robot
from calib.units import DEG

EX = Path(__file__).resolve().parents[1] / "examples"
UR10 = EX / "urdf" / "ur10_robot.urdf"


def _write(tmp_path, body, name="cal.toml"):
    f = tmp_path / name
    f.write_text(f'urdf = "{UR10}"\n' + body)
    return f


def _fk(robot, readings_edge):
    from calib.kinematics import Kinematics
    return Kinematics(robot).points(robot.joints_from_readings(np.atleast_2d(readings_edge) * robot.reading_edge_scale))


def test_reading_convention_theta3_is_j2_plus_j3(tmp_path):
    f = _write(tmp_path, """
[readings]
names = ["J1", "J2", "J3", "J4", "J5", "J6"]
[readings.joints]
shoulder_pan_joint = { J1 = 1.0 }
shoulder_lift_joint = { J2 = 1.0 }
elbow_joint = { J2 = 1.0, J3 = 1.0 }
wrist_1_joint = { J4 = 1.0, offset_deg = 90.0 }
wrist_2_joint = { J5 = 1.0 }
wrist_3_joint = { J6 = -1.0 }
""")
    cal = load_robot(f)
    plain = robot_from_urdf(UR10)
    assert cal.reading_names == ("J1", "J2", "J3", "J4", "J5", "J6")
    r = np.array([10.0, -30.0, 50.0, 20.0, 40.0, 60.0])
    joints = np.array([10.0, -30.0, 20.0, 110.0, 40.0, -60.0])        # worked out by hand from the table above
    np.testing.assert_allclose(_fk(cal, r), _fk(plain, joints), atol=1e-9)


def test_tool_points_base_and_tolerances(tmp_path):
    f = _write(tmp_path, """
base_link = "base_link"
[tool.points]
A = [0.0, 0.0, 100.0]
B = [50.0, 0.0, 0.0]
[base]
xyz_mm = [1000.0, 0.0, 0.0]
rpy_deg = [0.0, 0.0, 90.0]
[tolerances]
"elbow_joint.a_mm" = 0.5
"shoulder_lift_joint.alpha_deg" = 0.1
"base.z_mm" = 10.0
""")
    cal = load_robot(f)
    plain = robot_from_urdf(UR10, "base_link")
    assert set(cal.tool_points_mm) == {"A", "B"}
    assert cal.tolerances == {"j3.a_mm": 0.5, "j2.alpha_rad": pytest.approx(0.1 * DEG), "base.z_mm": 10.0}
    # the base puts the base link at x = 1000 turned 90 deg about z: a point at base-link (x, y) is at (1000 - y, x)
    p0 = _fk(plain, np.zeros(6))[0]
    from calib.kinematics import Kinematics
    kin = Kinematics(cal)
    got = kin.points(np.zeros((1, 6)), kin.params_with_tool(cal.tool_points_mm["A"]))[0]
    # tool point A is 100 mm along wrist_3_link's z from its origin; with no base, p0 is that origin
    assert np.linalg.norm(got - np.array([1000 - p0[1], p0[0], p0[2]])) == pytest.approx(100.0, abs=1e-9)


def test_masses_and_drives_replace_the_urdf(tmp_path):
    f = _write(tmp_path, """
[masses.forearm_link]
mass_kg = 5.0
com_mm = [0.0, 0.0, 0.0]
[drives.elbow_joint]
gear_ratio = 101.0
encoder_counts_per_rev = 4096
""")
    cal = load_robot(f)
    assert cal.mass_kg[2] == 5.0 and cal.gear_ratio[2] == 101.0 and cal.counts_per_rev[2] == 4096


@pytest.mark.parametrize("body,match", [
    ('[readings]\nnames = ["J1"]\n[readings.joints]\nelbow_joint = { J9 = 1.0 }\n',
     r"cal.toml: readings.joints.elbow_joint.J9: reading 'J9' is not one of the readings \(J1\)"),
    ('tip_link = "hand"\n', "tip link 'hand' is not in the URDF"),
    ('[tolerances]\n"elbow_joint.q_mm" = 1.0\n', "tolerances.elbow_joint.q_mm: is not a parameter"),
    ('[masses.nolink]\nmass_kg = 1.0\n', "masses.nolink: is not a link"),
    ('[drives.wrist_3_joint]\ngear_ratio = 0.0\nencoder_counts_per_rev = 10\n', "gear_ratio: must not be zero"),
])
def test_bad_description_is_one_line(tmp_path, body, match):
    with pytest.raises(RobocalError, match=match):
        load_robot(_write(tmp_path, body))


def test_shipped_tiago_description_loads():
    robot = load_robot(EX / "tiago" / "tiago_mocap.toml")
    assert robot.joint_names[0] == "torso_lift_joint" and "1" in robot.tool_points_mm
    assert robot.tolerances["j2.a_mm"] == 2.0


def test_reading_conventions_and_base_link_survive_the_written_description(tmp_path):
    """robot_to_toml (the model JSON's robot) keeps the readings and frame 0 in the base link."""
    from calib.robot import parse_robot, robot_to_toml
    f = _write(tmp_path, """
[readings]
names = ["shoulder_pan_joint", "shoulder_lift_joint", "J3", "J4", "wrist_2_joint", "wrist_3_joint"]
[readings.joints]
elbow_joint = { shoulder_lift_joint = 1.0, J3 = 1.0 }
wrist_1_joint = { J4 = 1.0, offset_deg = 90.0 }
""")
    cal = load_robot(f)
    again = parse_robot(robot_to_toml(cal), "again")
    assert again.reading_names == cal.reading_names
    np.testing.assert_allclose(again.reading_matrix, cal.reading_matrix)
    np.testing.assert_allclose(again.reading_offset, cal.reading_offset, atol=1e-12)
    np.testing.assert_allclose(again.frame0_in_base, cal.frame0_in_base, atol=1e-9)
    r = np.array([10.0, -30.0, 50.0, 20.0, 40.0, 60.0])
    np.testing.assert_allclose(_fk(again, r), _fk(cal, r), atol=1e-9)
