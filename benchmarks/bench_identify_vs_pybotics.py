"""Benchmark: robocal's full identification against a geometric-only calibration with pybotics, same data, one run.

Data: the Puma 560 twin (the thesis's effects: transmission errors on joints 4 and 6, two-slope compliance on joints
3 and 4, coupling 5 -> 6), measured by the two simulated theodolites (3" readings, points by intersection), half the
poses with a 5 kg payload.  ``--poses`` training poses, ``--holdout`` held-out poses.

* robocal: geometry + base + tool + running errors (about 60 parameters before the identifiability guard), analytic
  Jacobian, per-point covariance weighting;
* pybotics 3.1 (PyPI): its MDH model of the same robot (converted from the description), every kinematic parameter,
  tool position and world frame free, ``scipy.optimize.least_squares`` on its per-pose scalar error, from the same
  starting base pose.

Prints time and held-out accuracy (RMS and max distance to the true tool point) for both.  pybotics pins numpy < 2
but runs on numpy 2: install it with ``pip install --no-deps pybotics==3.1.2`` (attrs comes with hypothesis).
"""
from __future__ import annotations

import argparse
import os
import time

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import numpy as np  # noqa: E402

from calib.effects import effect_from_text  # noqa: E402
from calib.identify import PointObservations, identify, initial_base  # noqa: E402
from calib.model import MeasurementModel  # noqa: E402
from calib.theodolite import intersect  # noqa: E402
from calib.twin import Twin  # noqa: E402

EFFECTS = ("transmission_error:2:1.0:2", "transmission_error:3:1.0:2", "transmission_error:4:0.9:2",
           "transmission_error:6:1.8:2", "joint_compliance:2", "joint_compliance:3", "joint_compliance:4",
           "cross_coupling:6:5", "cross_coupling:5:4", "cross_coupling:6:4")


def measure(tw: Twin, n: int):
    q = tw.random_poses(n)
    ctx = tw.context(n, payload_kg=np.where(np.arange(n) % 2 == 0, 0.0, 5.0))
    m = tw.measure(q, ctx)
    k = len(tw.stations)
    pts = intersect(tw.stations, [(m.readings_rad[:, 2 * i], m.readings_rad[:, 2 * i + 1]) for i in range(k)])
    return q, ctx, m, pts


def rot(axis, a):
    c, s = np.cos(a), np.sin(a)
    return {"x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]), "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def pybotics_fit(robot, base_params, q_train, p_train, q_test):
    """pybotics MDH model of the description; returns (seconds, predicted held-out points)."""
    from scipy.optimize import least_squares

    from pybotics.optimization import OptimizationHandler, optimize_accuracy
    from pybotics.robot import Robot as PRobot

    # standard DH A_j = Rz(th) Tz(d) Tx(a) Rx(al)  ->  MDH link j = [alpha_{j-1}, a_{j-1}, theta_j, d_j]
    n = robot.n
    rows = []
    for j in range(n):
        al_prev = robot.alpha_rad[j - 1] if j else 0.0
        a_prev = robot.a_mm[j - 1] if j else 0.0
        rows.append([al_prev, a_prev, robot.theta_offset_rad[j], robot.d_mm[j]])
    pr = PRobot.from_parameters(np.array(rows))
    tool = np.eye(4)
    tool[:3, :3] = rot("x", robot.alpha_rad[-1])
    tool[:3, 3] = [robot.a_mm[-1], 0.0, 0.0]
    pr.tool.matrix = tool
    x, y, z, yaw, pitch, roll = base_params
    world = np.eye(4)
    world[:3, :3] = rot("z", yaw) @ rot("y", pitch) @ rot("x", roll)
    world[:3, 3] = [x, y, z]
    pr.world_frame = world
    handler = OptimizationHandler(robot=pr, kinematic_chain_mask=[True] * (4 * n),
                                  tool_mask=[True, True, True, False, False, False], world_mask=[True] * 6)
    t0 = time.perf_counter()
    res = least_squares(optimize_accuracy, handler.generate_optimization_vector(),
                        args=(handler, q_train, p_train), verbose=0)
    handler.apply_optimization_vector(res.x)
    seconds = time.perf_counter() - t0
    pred = np.array([handler.robot.fk(qi)[:3, 3] for qi in q_test])
    return seconds, pred, res.x.size


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--poses", type=int, default=500)
    ap.add_argument("--holdout", type=int, default=200)
    ap.add_argument("--seed", type=int, default=2026)
    args = ap.parse_args()
    tw = Twin(seed=args.seed)
    q, ctx, m, pts = measure(tw, args.poses)
    q_h, ctx_h, m_h, _ = measure(tw, args.holdout)
    truth_h = m_h.point_true_mm

    model = MeasurementModel(tw.robot, [effect_from_text(s) for s in EFFECTS])
    obs = PointObservations(m.q_read_rad, pts.point_mm, pts.cov_mm2, ctx=ctx)
    t0 = time.perf_counter()
    res = identify(model, obs)
    t_robocal = time.perf_counter() - t0
    pred = model.points(m_h.q_read_rad, ctx_h, res.theta)
    e = np.linalg.norm(pred - truth_h, axis=1)
    geo = MeasurementModel(tw.robot)
    t0 = time.perf_counter()
    res_g = identify(geo, PointObservations(m.q_read_rad, pts.point_mm, pts.cov_mm2, ctx=ctx))
    t_geo = time.perf_counter() - t0
    e_g = np.linalg.norm(geo.points(m_h.q_read_rad, ctx_h, res_g.theta) - truth_h, axis=1)

    print(f"robocal benchmark: identification, {args.poses} training poses, {args.holdout} held out "
          f"(Puma 560 twin with the thesis's effects, theodolite-intersected points)")
    print(f"  {'method':<58}{'params':>7}{'time s':>9}{'RMS mm':>9}{'max mm':>9}")
    print(f"  {'robocal full (geometry + running errors)':<58}{len(model.names) - 0:>7d}{t_robocal:>9.2f}"
          f"{np.sqrt(np.mean(e ** 2)):>9.4f}{e.max():>9.4f}")
    print(f"  {'  of which estimated after the identifiability guard':<58}{len(res.free):>7d}")
    print(f"  {'robocal geometric only':<58}{len(res_g.free):>7d}{t_geo:>9.2f}"
          f"{np.sqrt(np.mean(e_g ** 2)):>9.4f}{e_g.max():>9.4f}")
    try:
        import pybotics  # noqa: F401
    except ImportError:
        print("  pybotics: not installed (pip install --no-deps pybotics==3.1.2) — comparison skipped")
        return
    base0 = initial_base(geo, m.q_read_rad, pts.point_mm)
    base_params = [base0[geo.index[f"base.{k}"]] for k in ("x_mm", "y_mm", "z_mm", "yaw_rad", "pitch_rad",
                                                               "roll_rad")]
    t_pb, pred_pb, n_pb = pybotics_fit(tw.robot, base_params, m.q_read_rad, pts.point_mm, m_h.q_read_rad)
    e_pb = np.linalg.norm(pred_pb - truth_h, axis=1)
    print(f"  {'pybotics 3.1 geometric (MDH, tool, world; scalar residuals)':<58}{n_pb:>7d}{t_pb:>9.2f}"
          f"{np.sqrt(np.mean(e_pb ** 2)):>9.4f}{e_pb.max():>9.4f}")
    print(f"  robocal full is {t_pb / t_robocal:.1f}x faster than pybotics while estimating "
          f"{len(res.free) - n_pb:+d} more parameters")


if __name__ == "__main__":
    main()
