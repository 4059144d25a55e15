"""Forward kinematics and the identification Jacobian of the chain."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from calib.kinematics import Kinematics
from calib.loading import load_robot
from calib.units import DEG
from tests.fakes.oracle.chain import numeric_jacobian, rot_z
from tests.fakes.thesis_puma import ThesisPuma, six_e

from pathlib import Path

DATA = Path(__file__).parent / "data"


def thesis_A_matrices(q, a1, a2, d1, d2, d3):
    """The six A-matrices of section 3.4 typed in as printed (independent of calib.kinematics)."""
    C = np.cos(q)
    S = np.sin(q)
    A1 = np.array([[C[0], 0, -S[0], 0], [S[0], 0, C[0], 0], [0, -1, 0, 0], [0, 0, 0, 1]])
    A2 = np.array([[C[1], S[1], 0, a1 * C[1]], [S[1], -C[1], 0, a1 * S[1]], [0, 0, -1, d1], [0, 0, 0, 1]])
    A3 = np.array([[C[2], 0, S[2], a2 * C[2]], [S[2], 0, -C[2], a2 * S[2]], [0, 1, 0, 0], [0, 0, 0, 1]])
    A4 = np.array([[C[3], 0, -S[3], 0], [S[3], 0, C[3], 0], [0, -1, 0, d2], [0, 0, 0, 1]])
    A5 = np.array([[C[4], 0, S[4], 0], [S[4], 0, -C[4], 0], [0, 1, 0, 0], [0, 0, 0, 1]])
    A6 = np.array([[C[5], -S[5], 0, 0], [S[5], C[5], 0, 0], [0, 0, 1, d3], [0, 0, 0, 1]])
    return A1 @ A2 @ A3 @ A4 @ A5 @ A6


def test_fk_matches_section_3_4_matrices(puma, rng):
    """robocal's chain and the tests' oracle (tests/fakes/oracle: the general A_j with Fig 3.5's twists) both equal
    the six matrices typed in as printed."""
    kin = Kinematics(puma)
    oracle = ThesisPuma()
    q = rng.uniform(-np.pi, np.pi, (50, 6))
    fp = kin.forward(q)
    for i in range(len(q)):
        T = thesis_A_matrices(q[i], 432.0, -20.3, 149.1, 432.0, 57.1)
        np.testing.assert_allclose(fp.point[i], T[:3, 3], atol=1e-9)
        np.testing.assert_allclose(fp.flange_R[i], T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(oracle.frames(q[i])[6], T, atol=1e-9)


def test_tool_point_follows_6E(puma, rng):
    """With the thesis's ^6E the tool point sits at -(Xt, Yt, Zt) in frame 6."""
    Xt, Yt, Zt = 12.0, -30.0, -150.0
    kin = Kinematics(puma.with_tool({"P": [-Xt, -Yt, -Zt]}))
    q = rng.uniform(-np.pi, np.pi, (20, 6))
    pts = kin.points(q)
    for i in range(len(q)):
        T = thesis_A_matrices(q[i], 432.0, -20.3, 149.1, 432.0, 57.1) @ six_e(Xt, Yt, Zt)
        np.testing.assert_allclose(pts[i], T[:3, 3], atol=1e-9)


def test_ready_position_is_upright(puma):
    """Fig 3.5's READY position [0, -90, 90, 0, 0, 0]: the arm stands straight up above the shoulder."""
    p = Kinematics(puma).points(np.array([[0, -90, 90, 0, 0, 0]]) * DEG)[0]
    assert p[2] == pytest.approx(432.0 + 432.0 + 57.1)
    assert p[1] == pytest.approx(149.1)
    assert abs(p[0]) == pytest.approx(20.3)


def test_robotics_toolbox_published_pose():
    """RTB DH.Puma560 at qn = [0, 45, 180, 0, 45, 0] deg: printed as position (0.5963, -0.1501, 0.6575) m with
    rotation [[0, 0, 1], [0, 1, 0], [-1, 0, 0]] (RVC3-python README, rvctool example)."""
    kin = Kinematics(load_robot(DATA / "rtb_puma560_dh.toml"))
    fp = kin.forward(np.array([[0, np.pi / 4, np.pi, 0, np.pi / 4, 0]]))
    np.testing.assert_allclose(fp.point[0] / 1000, [0.5963, -0.1501, 0.6575], atol=6e-5)
    np.testing.assert_allclose(fp.flange_R[0], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-9)


def _fd_jacobian(kin, q, params, h=1e-6):
    return numeric_jacobian(lambda th: kin.points(q, th), params, h)


def test_parameter_jacobian_matches_finite_differences(puma, rng):
    kin = Kinematics(puma.with_tool({"P": [30.0, -20.0, 120.0]}))
    q = rng.uniform(-2, 2, (25, 6))
    params = kin.nominal + rng.normal(0, 1e-3, kin.P)       # away from the exact nominal symmetry
    pts, J, Jq = kin.jacobians(q, params)
    np.testing.assert_allclose(J, _fd_jacobian(kin, q, params), atol=2e-6)
    # joint Jacobian: moving joint j equals moving its theta offset
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = 1e-6
        fd = (kin.points(q + dq, params) - kin.points(q - dq, params)) / 2e-6
        np.testing.assert_allclose(Jq[:, :, j], fd, atol=2e-6)


def test_every_parameter_is_named_with_a_unit(puma):
    kin = Kinematics(puma)
    assert len(kin.names) == len(set(kin.names)) == 6 + 6 * 5 + 3
    assert all(n.endswith(("_mm", "_rad")) for n in kin.names)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6))
def test_vectorised_equals_one_by_one(qs):
    kin = Kinematics(load_robot())
    q = np.array([qs, [0.1] * 6, qs[::-1]])
    batch = kin.points(q)
    single = np.vstack([kin.points(q[i:i + 1]) for i in range(3)])
    np.testing.assert_allclose(batch, single, atol=1e-12)


def test_base_transform_moves_points_rigidly(puma, rng):
    kin = Kinematics(puma)
    q = rng.uniform(-2, 2, (10, 6))
    p0 = kin.points(q)
    params = kin.nominal.copy()
    params[kin.index["base.x_mm"]] = 100.0
    params[kin.index["base.yaw_rad"]] = 0.3
    p1 = kin.points(q, params)
    R = rot_z(0.3)[:3, :3]
    np.testing.assert_allclose(p1, p0 @ R.T + [100.0, 0, 0], atol=1e-9)


def test_prismatic_joint_adds_to_d(tmp_path):
    from calib.robot import parse_robot, robot_to_toml
    text = """
[[joint]]
type = "prismatic"
a_mm = 0.0
d_mm = 100.0
alpha_deg = 0.0
limits_mm = [0.0, 350.0]
gear_ratio = 1.0
encoder_counts_per_rev = 1000

[[joint]]
a_mm = 200.0
d_mm = 0.0
alpha_deg = 0.0
limits_deg = [-180.0, 180.0]
gear_ratio = 1.0
encoder_counts_per_rev = 1000
"""
    robot = parse_robot(text, "lift.toml")
    assert robot.prismatic.tolist() == [True, False]
    kin = Kinematics(robot)
    p = kin.points(np.array([[50.0, np.pi / 2]]))[0]
    np.testing.assert_allclose(p, [0.0, 200.0, 150.0], atol=1e-9)
    again = parse_robot(robot_to_toml(robot))
    np.testing.assert_allclose(again.limits_rad, robot.limits_rad)
    assert again.prismatic.tolist() == [True, False]


def test_pose_csv_reads_prismatic_joints_in_mm(tmp_path):
    from calib.posecsv import read_pose_csv, write_pose_csv
    f = tmp_path / "p.csv"
    f.write_text("q1,q2\n250.0,90.0\n")
    t = read_pose_csv(f, 2, prismatic=[True, False])
    np.testing.assert_allclose(t.q_rad, [[250.0, np.pi / 2]])
    write_pose_csv(tmp_path / "o.csv", t.q_rad, prismatic=[True, False])
    np.testing.assert_allclose(read_pose_csv(tmp_path / "o.csv", 2, prismatic=[True, False]).q_rad, t.q_rad)


def test_one_pose_of_a_batch_is_that_pose_alone(puma, rng):
    """ChainPass.pose(k): what code that walks a batch pose by pose reads (frames, screws, gravity)."""
    kin = Kinematics(puma.with_tool({"P": [30.0, -20.0, 120.0]}))
    q = rng.uniform(-2, 2, (6, 6))                      # as many poses as base parameters: no shape confusion
    params = kin.nominal + rng.normal(0, 1e-3, kin.P)
    batch = kin.forward(q, params)
    for k in (0, 4):
        one, alone = batch.pose(k), kin.forward(q[k:k + 1], params)
        for attr in ("point", "frame_R", "frame_t", "elem_axis", "elem_origin"):
            np.testing.assert_allclose(getattr(one, attr), getattr(alone, attr), atol=1e-12, err_msg=attr)
        np.testing.assert_allclose(one.gravity(), alone.gravity(), atol=1e-12)
        np.testing.assert_allclose(kin.element_jacobian(one), kin.element_jacobian(alone), atol=1e-12)


def test_small_and_large_batches_chain_the_same(puma, rng):
    """Below SMALL_BATCH poses a link step is one matmul, above it rows of multiply-adds: the same frames."""
    from calib.kinematics import SMALL_BATCH
    kin = Kinematics(puma.with_tool({"P": [30.0, -20.0, 120.0]}))
    q = rng.uniform(-3, 3, (2 * SMALL_BATCH, 6))
    params = kin.nominal + rng.normal(0, 1e-2, kin.P)
    big = kin.forward(q, params)
    for lo in range(0, len(q), 8):
        small = kin.forward(q[lo:lo + 8], params)
        np.testing.assert_allclose(small.frame_R, big.frame_R[lo:lo + 8], atol=1e-14)
        np.testing.assert_allclose(small.point, big.point[lo:lo + 8], atol=1e-11)
