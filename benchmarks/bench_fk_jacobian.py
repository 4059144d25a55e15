"""Benchmark: robocal's forward kinematics and identification Jacobian against a plain vectorised numpy chain.

Same poses, same run, one BLAS thread.  The plain implementation below imports nothing from ``calib`` but the robot
description; its matrices are the tests' oracle (tests/fakes/oracle/chain.py, which broadcasts over poses): the same
chain -- base ``Tx Ty Tz Rz Ry Rx``, per link the DH A-matrix ``Rz(theta) Tz(d) Tx(a) Rx(alpha)`` as printed times
the Hayati ``Ry(beta)``, tool point in frame n -- as (N, 4, 4) homogeneous matrices multiplied link by link, and its
Jacobian as the textbook geometric columns (``z x (p - o)`` for
a rotation, the axis for a translation), vectorised over poses.  The benchmark first checks that both give the same
points and Jacobian (to 1e-9 mm), then prints poses/s side by side with the ratio robocal / plain and the target
(>= 0.7, issue 18).  The last lines are the full measurement model (thesis effects and their Jacobian), which has
no plain counterpart, with the torque-derivative term as the rule decides (left out for the thesis's compliances)
and forced on.

Run: ``PYTHONPATH=. python benchmarks/bench_fk_jacobian.py [--poses 10000] [--repeat 7]``.
"""
from __future__ import annotations

import argparse
import dataclasses
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"          # one core: the figures compare the numpy code, not the BLAS threads

import time  # noqa: E402

import numpy as np  # noqa: E402

from calib.effects import thesis_effects  # noqa: E402
from calib.kinematics import Kinematics  # noqa: E402
from calib.model import MeasurementModel  # noqa: E402
from calib.robot import load_robot  # noqa: E402
from tests.fakes.oracle.chain import base_matrix, hayati_matrix  # noqa: E402

TARGET = 0.7


# -- the plain implementation: the tests' oracle chain (tests/fakes/oracle/chain.py), vectorised over poses ------
class PlainChain:
    """The chain of a robot description as plain numpy 4x4 products (revolute joints)."""

    def __init__(self, robot):
        self.r = robot
        roll, pitch, yaw = robot.base_rpy_rad
        self.base = base_matrix(robot.base_xyz_mm, yaw, pitch, roll)
        self.yaw = yaw
        self.tool = np.asarray(robot.tool_point(), float)

    def link_matrices(self, q_j, j) -> np.ndarray:
        """(N, 4, 4) DH A-matrix of link j times the Hayati Ry(beta)."""
        r = self.r
        return hayati_matrix(q_j + r.theta_offset_rad[j], r.d_mm[j], r.a_mm[j], r.alpha_rad[j], r.beta_rad[j])

    def frames(self, q) -> list[np.ndarray]:
        T = np.broadcast_to(self.base, (len(q), 4, 4))
        out = [T]
        for j in range(self.r.n):
            T = T @ self.link_matrices(q[:, j], j)
            out.append(T)
        return out

    def fk(self, q) -> np.ndarray:
        T = np.broadcast_to(self.base, (len(q), 4, 4))
        for j in range(self.r.n):
            T = T @ self.link_matrices(q[:, j], j)
        return T[:, :3, :3] @ self.tool + T[:, :3, 3]

    def fk_jacobian(self, q):
        """Points (N, 3) and d point / d (base 6, per link theta, d, a, alpha, beta, tool 3) (N, 3, 6 + 5n + 3)."""
        T = self.frames(q)
        n = self.r.n
        p = T[-1][:, :3, :3] @ self.tool + T[-1][:, :3, 3]
        J = np.empty((len(q), 3, 6 + 5 * n + 3))
        o0 = T[0][:, :3, 3]
        J[:, :, 0:3] = np.eye(3)
        J[:, :, 3] = np.cross([0.0, 0.0, 1.0], p - o0)
        J[:, :, 4] = np.cross([-np.sin(self.yaw), np.cos(self.yaw), 0.0], p - o0)
        J[:, :, 5] = np.cross(T[0][:, :3, 0], p - o0)
        for j in range(n):
            z, o = T[j][:, :3, 2], T[j][:, :3, 3]
            xj, yj, zj, oj = T[j + 1][:, :3, 0], T[j + 1][:, :3, 1], T[j + 1][:, :3, 2], T[j + 1][:, :3, 3]
            b = self.r.beta_rad[j]
            x_common = np.cos(b) * xj + np.sin(b) * zj          # common normal: x before the beta rotation
            c = 6 + 5 * j
            J[:, :, c] = np.cross(z, p - o)
            J[:, :, c + 1] = z
            J[:, :, c + 2] = x_common
            J[:, :, c + 3] = np.cross(x_common, p - oj)
            J[:, :, c + 4] = np.cross(yj, p - oj)
        J[:, :, -3:] = T[-1][:, :3, :3]
        return p, J


# -- timing ---------------------------------------------------------------------------------------------------------
def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poses", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    # the thesis Puma with a placed base, a tool point and a Hayati beta on the parallel axes 2-3, so that every
    # part of the chain is exercised by the agreement check
    robot = load_robot().with_tool({"P": [30.0, -20.0, 120.0]})
    robot = dataclasses.replace(robot, base_xyz_mm=np.array([474.9, 2853.0, 184.9]),
                                base_rpy_rad=np.array([0.01, -0.02, 0.3]),
                                beta_rad=np.where(robot.hayati, 0.002, 0.0))
    kin = Kinematics(robot)
    plain = PlainChain(robot)
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (args.poses, robot.n))
    n = args.poses

    # the same numbers first
    p_ref, J_ref = plain.fk_jacobian(q)
    p_rc, J_rc, _ = kin.jacobians(q)
    assert np.allclose(plain.fk(q), p_ref, atol=1e-9, rtol=0)
    assert np.allclose(kin.points(q), p_ref, atol=1e-9, rtol=0), "robocal and plain FK disagree"
    assert np.allclose(J_rc, J_ref, atol=1e-9, rtol=0), "robocal and plain Jacobians disagree"

    # interleaved, best of N each
    rows = []
    for label, ours, ref in (("forward kinematics", lambda: kin.points(q), lambda: plain.fk(q)),
                             ("FK + Jacobian", lambda: kin.jacobians(q), lambda: plain.fk_jacobian(q))):
        t_ours, t_ref = np.inf, np.inf
        for _ in range(args.repeat):
            t_ours = min(t_ours, best_of(ours, 1))
            t_ref = min(t_ref, best_of(ref, 1))
        rows.append((label, t_ours, t_ref))
    model = MeasurementModel(robot, thesis_effects())
    t_model = best_of(lambda: model.evaluate(q, jacobian=True), max(1, args.repeat // 2))
    t_exact = best_of(lambda: model.evaluate(q, jacobian=True, torque_derivative=True), max(1, args.repeat // 4))

    print(f"robocal benchmark: forward kinematics (+ Jacobian, 3 x {kin.P} per pose), {n} poses, one BLAS thread, "
          f"Puma 560 with Hayati beta and a tool point")
    print(f"  {'':22s} {'robocal poses/s':>16s} {'plain numpy poses/s':>20s} {'ratio':>7s}  target")
    for label, t_ours, t_ref in rows:
        ratio = t_ref / t_ours
        ok = "ok" if ratio >= TARGET else "BELOW"
        print(f"  {label:22s} {n / t_ours:16,.0f} {n / t_ref:20,.0f} {ratio:7.2f}  >= {TARGET} {ok}")
    print(f"  full model + thesis effects + Jacobian ({model.P} parameters): {n / t_model:12,.0f} poses/s "
          f"({t_model * 1e3:.1f} ms; torque term left out by the rule, calib.model.torque_term_matters)")
    print(f"  the same with the torque term forced on:                  {n / t_exact:12,.0f} poses/s "
          f"({t_exact * 1e3:.1f} ms)")
    print("  (agreement checked: points and Jacobian equal to 1e-9 mm)")


if __name__ == "__main__":
    main()
