"""What several stages read off a run of steps about one joint: the steps grouped by joint, the joint readings of a
step (encoder counts, else the commanded pose), and the angle a joint turned from two targets A1, A2 on the extended
tool (about a given axis, or about the run's own axis fitted from A2)."""
from __future__ import annotations

import numpy as np

from calib.angles import wrap_angle
from calib.estimators.axes import check_axis
from calib.estimators.transmission import joint_angles, joint_angles_fitted_axis
from calib.robot import Robot
from calib.units import DEG

from offline.reduction.context import Located


def by_joint(steps: list[dict]) -> dict[int, list[dict]]:
    """A procedure's steps grouped by the joint they exercise (``spec.meta.joint``), each group in the order of its
    ``meta.index`` (the order recorded where a step has none)."""
    out: dict[int, list[dict]] = {}
    for st in steps:
        out.setdefault(st["spec"]["meta"]["joint"], []).append(st)
    for sts in out.values():
        sts.sort(key=lambda s: s["spec"]["meta"].get("index", 0))
    return out


def encoder_q(step: dict, robot: Robot) -> np.ndarray | None:
    """The step's joint readings from its tapped encoder counts (mean over its window), None without a tap."""
    c = step.get("counts")
    if c is None or len(c) == 0:
        return None
    return robot.joint_from_counts(np.mean(c, 0))


def reading_q(step: dict, robot: Robot) -> np.ndarray:
    """The step's joint readings: from the encoder counts when tapped, else the pose commanded (rad)."""
    q = encoder_q(step, robot)
    return np.asarray(step["spec"]["pose_deg"], float) * DEG if q is None else q


def relative_error(measured_rad: np.ndarray, reading_rad: np.ndarray) -> np.ndarray:
    """Measured angle turned minus the readings' turn from the first step, wrapped (both sides wrap differently
    past 180 deg)."""
    return wrap_angle(measured_rad - (reading_rad - reading_rad[0]))


def angles_about(steps: list[dict], points: Located, axis_n: np.ndarray):
    """Angle turned about ``axis_n`` from the first step, per step, from A1 -> A2
    (:func:`calib.estimators.transmission.joint_angles`), with their 1-sigma and covariance (the stations' errors
    are common to every step); NaN where a step lacks A1 or A2."""
    out, cov = np.full(len(steps), np.nan), np.full((len(steps), len(steps)), np.nan)
    ok = [i for i, st in enumerate(steps) if {"A1", "A2"} <= set(points(st))]
    if ok:
        pairs = [(points(steps[i])["A1"], points(steps[i])["A2"]) for i in ok]
        read = np.array([np.block([[a.cov_reading_mm2, np.zeros((3, 3))], [np.zeros((3, 3)), b.cov_reading_mm2]])
                         for a, b in pairs])
        D = np.array([np.concatenate([a.d_station, b.d_station]) for a, b in pairs])
        out[ok], cov[np.ix_(ok, ok)] = joint_angles(np.array([a.point_mm for a, _ in pairs]),
                                                    np.array([b.point_mm for _, b in pairs]), read, axis_n, D,
                                                    points.station_fit.cov)
    return out, np.sqrt(np.diag(cov)), cov


def angles_about_own_axis(steps: list[dict], points: Located, joint: int):
    """Angles of a run about the joint's own axis, fitted from A2 over the run itself (a wide span at a large radius
    beats the short sweep), with the axis's error in their covariance
    (:func:`calib.estimators.transmission.joint_angles_fitted_axis`): ``(angles, sigmas, cov)`` as
    :func:`angles_about`; None when fewer than 4 steps have both targets."""
    ok = [i for i, st in enumerate(steps) if {"A1", "A2"} <= set(points(st))]
    if len(ok) < 4:
        return None
    pairs = [(points(steps[i])["A1"], points(steps[i])["A2"]) for i in ok]
    U = points.covariance([t for p in pairs for t in p])
    A1, A2 = (np.array([p[k].point_mm for p in pairs]) for k in (0, 1))
    iA2 = (np.arange(len(ok))[:, None] * 6 + np.arange(3, 6)).ravel()
    check_axis(A2, U[np.ix_(iA2, iA2)], joint=f"j{joint}")            # the points lie on a circle
    out, cov = np.full(len(steps), np.nan), np.full((len(steps), len(steps)), np.nan)
    out[ok], cov[np.ix_(ok, ok)], _ = joint_angles_fitted_axis(A1, A2, U)
    return out, np.sqrt(np.diag(cov)), cov
