"""Benchmark: forward kinematics plus the full identification Jacobian for 10,000 poses, on one core.

Prints poses per second for the vectorised chain (calib.kinematics) and, for scale, for a plain per-pose loop of
4x4 DH matrices (forward kinematics only, no Jacobian) on a subset.  Run: ``python benchmarks/bench_fk_jacobian.py``.
"""
from __future__ import annotations

import argparse
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")          # one core, as the issue asks

import time  # noqa: E402

import numpy as np  # noqa: E402

from calib.kinematics import Kinematics  # noqa: E402
from calib.model import MeasurementModel  # noqa: E402
from calib.robot import load_robot  # noqa: E402
from calib.effects import thesis_effects  # noqa: E402


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def loop_fk(robot, q):
    out = np.empty((len(q), 3))
    for i, qi in enumerate(q):
        T = np.eye(4)
        for j in range(robot.n):
            th = qi[j] + robot.theta_offset_rad[j]
            ct, st = np.cos(th), np.sin(th)
            ca, sa = np.cos(robot.alpha_rad[j]), np.sin(robot.alpha_rad[j])
            A = np.array([[ct, -st * ca, st * sa, robot.a_mm[j] * ct], [st, ct * ca, -ct * sa, robot.a_mm[j] * st],
                          [0, sa, ca, robot.d_mm[j]], [0, 0, 0, 1]])
            T = T @ A
        out[i] = T[:3, 3]
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--poses", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    robot = load_robot()
    kin = Kinematics(robot)
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (args.poses, robot.n))
    n = args.poses
    t_fk = best_of(lambda: kin.points(q), args.repeat)
    t_jac = best_of(lambda: kin.jacobians(q), args.repeat)
    model = MeasurementModel(robot, thesis_effects())
    t_model = best_of(lambda: model.evaluate(q, jacobian=True), max(1, args.repeat // 2))
    m = min(n, 1000)
    t_loop = best_of(lambda: loop_fk(robot, q[:m]), 1) * n / m
    P = kin.P
    print(f"robocal benchmark: forward kinematics + Jacobian, {n} poses, one core (Puma 560, {P} parameters)")
    print(f"  forward kinematics only          {t_fk * 1e3:9.1f} ms   {n / t_fk:12,.0f} poses/s")
    print(f"  FK + Jacobian (3 x {P} per pose)  {t_jac * 1e3:9.1f} ms   {n / t_jac:12,.0f} poses/s")
    print(f"  full model + effects + Jacobian  {t_model * 1e3:9.1f} ms   {n / t_model:12,.0f} poses/s "
          f"({model.P} parameters, torque-aware)")
    print(f"  reference: per-pose 4x4 loop, FK only (extrapolated from {m}) "
          f"{t_loop * 1e3:9.1f} ms   {n / t_loop:12,.0f} poses/s")
    print(f"  vectorised FK + Jacobian is {t_loop / t_jac:.0f}x the per-pose FK loop")


if __name__ == "__main__":
    main()
