"""The tests' oracle (tests/fakes/oracle) checked against what nobody here wrote -- scipy's rotations, the thesis's
eq 4.3.1 in the other direction, a central-difference of a known function -- and the one chain still written outside
it, the diagnosis's validation generator (sim/independent.py, shipped with robocal so it cannot import the
tests), held to the oracle's products and torques."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from sim.independent import TOOL_MM, Arm
from calib.loading import load_robot
from tests.fakes.oracle.beam import cantilever_deflection
from tests.fakes.oracle.chain import (a_matrix, axis_angle, axis_torques, base_matrix, dh_frames, hayati_matrix,
                                      numeric_jacobian, point_in, rot_x, rot_y, rot_z, rpy_matrix, trans)
from tests.fakes.oracle.effects import two_slope
from tests.fakes.oracle.stations import point_from_angles, thesis_angles


def test_rotations_equal_scipys():
    rng = np.random.default_rng(0)
    for r, p, y in rng.uniform(-3, 3, (20, 3)):
        np.testing.assert_allclose(rpy_matrix(r, p, y), Rotation.from_euler("xyz", [r, p, y]).as_matrix(), atol=1e-14)
        w = rng.normal(size=3)
        np.testing.assert_allclose(axis_angle(w, np.linalg.norm(w)), Rotation.from_rotvec(w).as_matrix(), atol=1e-14)
    # broadcast over poses: the (N, 4, 4) stack is the one-by-one matrices
    a = rng.uniform(-3, 3, 5)
    for k, R in enumerate(rot_z(a)):
        np.testing.assert_array_equal(R, rot_z(a[k]))


def test_a_matrix_is_its_four_factors():
    """Section 3.4's A_j written out equals Rot(z, theta) Trans(z, d) Trans(x, a) Rot(x, alpha)."""
    for th, d, a, al in np.random.default_rng(1).uniform(-3, 3, (10, 4)) * [1, 100, 100, 1]:
        np.testing.assert_allclose(a_matrix(th, d, a, al), rot_z(th) @ trans(0, 0, d) @ trans(a, 0, 0) @ rot_x(al),
                                   atol=1e-12)
        b = al / 7
        np.testing.assert_allclose(hayati_matrix(th, d, a, al, b), a_matrix(th, d, a, al) @ rot_y(b), atol=1e-12)


def test_stations_invert_through_eq_4_3_1():
    rng = np.random.default_rng(2)
    P = np.c_[rng.uniform(200, 1400, 30), rng.uniform(800, 3000, 30), rng.uniform(-500, 800, 30)]
    alpha, beta, phi_a, _ = thesis_angles(P, 1609.9)
    np.testing.assert_allclose(point_from_angles(alpha, beta, phi_a, 1609.9), P, atol=1e-8)


def test_numeric_jacobian_and_beam_on_known_answers():
    x = np.array([0.3, -1.2])
    J = numeric_jacobian(lambda v: np.array([np.sin(v[0]) * v[1], v[1] ** 3]), x)
    np.testing.assert_allclose(J, [[np.cos(0.3) * -1.2, np.sin(0.3)], [0.0, 3 * 1.44]], atol=1e-8)
    tip = 30.0 * 500.0 ** 3 / (3 * 2e11)                 # a cantilever's tip under its end load: P L^3 / 3 EI
    assert abs(cantilever_deflection(500.0, 500.0, 30.0, 2e11) / tip - 1) < 1e-8
    np.testing.assert_allclose(two_slope([-30.0, 10.0, 30.0], 1e3, 2e3, 20.0), [-0.025, 0.01, 0.025])


def test_the_validation_generators_chain_answers_to_the_oracle():
    robot = load_robot()
    arm = Arm.perturbed(robot, np.random.default_rng(3))
    arm.base = base_matrix([1500.0, 800.0, 200.0], 0.3, 0.01, -0.02)
    q = np.random.default_rng(4).uniform(-2, 2, (8, robot.n))
    got = arm.frames(q)
    payload = np.linspace(0, 5, len(q))
    tau = arm.torques(q, payload)
    for i in range(len(q)):
        F = dh_frames(arm.base, q[i] + arm.offset, arm.d, arm.a, arm.alpha, arm.beta)
        for k in range(robot.n + 1):
            np.testing.assert_allclose(got[k][i], F[k], atol=1e-9)
        g = arm.base[:3, :3] @ arm.gravity
        loads = [(point_in(F[k + 1], arm.com[k]), arm.mass[k] * g, k + 1) for k in range(robot.n)]
        loads.append((point_in(F[-1], TOOL_MM), payload[i] * g, robot.n))
        np.testing.assert_allclose(tau[i], axis_torques(F, loads), atol=1e-9)
