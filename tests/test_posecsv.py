"""The extended pose CSV: joint-name columns, units, targets, the data's own split, stations, polar readings."""
from pathlib import Path

import numpy as np
import pytest

from calib.errors import RobocalError
from calib.posecsv import read_pose_csv
from calib.loading import load_robot
from calib.units import DEG

EX = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def tiago():
    return load_robot(EX / "tiago" / "tiago_mocap.toml")


@pytest.fixture
def ur10(tmp_path):
    f = tmp_path / "ur10.toml"
    f.write_text(f'urdf = "{EX / "urdf" / "ur10_robot.urdf"}"\n[tool.points]\nR1 = [0, 0, 10.0]\nR2 = [0, 50.0, 10.0]\n'
                 'R3 = [50.0, 0, 10.0]\n')
    return load_robot(f)


NAMES = "shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint"


def _csv(tmp_path, text, name="d.csv"):
    f = tmp_path / name
    f.write_text(text)
    return f


def test_tiago_file_reads_by_joint_names_in_m_and_rad(tiago):
    with pytest.warns(UserWarning, match="x2, y2, z2"):
        t = read_pose_csv(EX / "tiago" / "qualysis_base_hand_calibration.csv", robot=tiago, angle_unit="rad",
                          length_unit="m")
    raw = np.loadtxt(EX / "tiago" / "qualysis_base_hand_calibration.csv", delimiter=",", skiprows=1)
    assert t.n == 34 and t.target == ["1"] * 34
    np.testing.assert_allclose(t.points_mm, raw[:, 0:3] * 1000.0)
    np.testing.assert_allclose(t.q_rad[:, 0], raw[:, 12] * 1000.0)      # torso lift: m -> mm
    np.testing.assert_allclose(t.q_rad[:, 1:], raw[:, 13:])             # arm joints: rad


def test_units_declared_in_the_file_and_a_conflict(tmp_path, ur10):
    f = _csv(tmp_path, f"# angle_unit = rad\n# length_unit: m\n{NAMES},x,y,z\n0.1,0.2,0.3,0.4,0.5,0.6,1,2,3\n")
    t = read_pose_csv(f, robot=ur10)
    np.testing.assert_allclose(t.q_rad[0], [0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    np.testing.assert_allclose(t.points_mm[0], [1000, 2000, 3000])
    with pytest.raises(RobocalError, match=r"d.csv: line 1: the file declares angle_unit rad, the command says deg"):
        read_pose_csv(f, robot=ur10, angle_unit="deg")


def test_long_targets_split_and_station(tmp_path, ur10):
    f = _csv(tmp_path, f"pose,target,split,station,{NAMES},x,y,z\n"
                       "p1,R1,fit,S1,0,10,20,30,40,50,1,2,3\n"
                       "p1,R2,fit,S1,0,10,20,30,40,50,4,5,6\n"
                       "p2,R3,test,S2,5,10,20,30,40,50,7,8,9\n")
    t = read_pose_csv(f, robot=ur10)
    assert t.target == ["R1", "R2", "R3"] and t.split == ["fit", "fit", "test"] and t.station == ["S1", "S1", "S2"]
    np.testing.assert_allclose(t.q_rad[2, 0], 5 * DEG)
    assert t.split_mask("test").tolist() == [False, False, True]
    assert t.subset(t.split_mask("fit")).target == ["R1", "R2"]


def test_wide_targets_expand_to_one_row_per_seen_target(tmp_path, ur10):
    f = _csv(tmp_path, f"{NAMES},xR1,yR1,zR1,xR2,yR2,zR2\n0,0,0,0,0,0,1,2,3,4,5,6\n1,0,0,0,0,0,7,8,9,,,\n")
    t = read_pose_csv(f, robot=ur10)
    assert t.target == ["R1", "R2", "R1"] and t.pose_id == ["2", "2", "3"]
    np.testing.assert_allclose(t.points_mm, [[1, 2, 3], [4, 5, 6], [7, 8, 9]])


def test_old_files_still_read(tmp_path):
    f = _csv(tmp_path, "q1,q2,q3,q4,q5,q6,x,y,z\n0,90,0,0,0,0,1,2,3\n")
    t = read_pose_csv(f, 6)
    np.testing.assert_allclose(t.q_rad[0, 1], np.pi / 2)
    assert t.target is None and t.split is None


def test_polar_and_orientation_columns(tmp_path, ur10):
    f = _csv(tmp_path, f"{NAMES},hz_deg,v_deg,dist_mm,rx_deg,ry_deg,rz_deg\n0,0,0,0,0,0,90,45,2000,0,0,180\n")
    t = read_pose_csv(f, robot=ur10)
    np.testing.assert_allclose(t.polar[0], [np.pi / 2, np.pi / 4, 2000])
    np.testing.assert_allclose(t.orientation_rad[0], [0, 0, np.pi])


@pytest.mark.parametrize("text,match", [
    (f"{NAMES},arm_9_joint,x,y,z\n0,0,0,0,0,0,0,1,2,3\n", r"line 1: column arm_9_joint is not a joint of the description"),
    (f"target,{NAMES},x,y,z\nR7,0,0,0,0,0,0,1,2,3\n", r"line 2: column target: 'R7' names no tool point .*R1, R2, R3"),
    (f"split,{NAMES},x,y,z\ntrain,0,0,0,0,0,0,1,2,3\n", r"line 2: column split: 'train' must be fit or test"),
    (f"pose,split,{NAMES},x,y,z\na,fit,0,0,0,0,0,0,1,2,3\na,test,0,0,0,0,0,0,1,2,3\n", r"line 3: pose 'a' is 'fit'"),
    (f"{NAMES},xA,yA,zA\n0,0,0,0,0,0,1,2,3\n", r"line 1: the target columns \(A\) name no tool point"),
])
def test_bad_rows_are_one_line(tmp_path, ur10, text, match):
    with pytest.raises(RobocalError, match=match) as e:
        read_pose_csv(_csv(tmp_path, text), robot=ur10)
    assert "d.csv" in str(e.value)
