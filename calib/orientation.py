"""6-D pose rows: a measured orientation beside the measured point, end to end.

Convention (stated in every output that uses it): ``rx_deg``, ``ry_deg``, ``rz_deg`` are the measured frame's
orientation in the instrument frame as fixed-axis roll-pitch-yaw, ``R = Rz(rz) Ry(ry) Rx(rx)`` (URDF's ``rpy``, scipy's
extrinsic ``"xyz"``); the frame's origin is the row's ``x, y, z``.  Default noise: :data:`DEFAULT_NOISE_DEG` per axis
(``identify --orientation-noise-deg``).

How a row enters a fit: as its point plus two more points :data:`LEVER_MM` along the measured frame's x and y axes
(targets ``T@x`` and ``T@y`` whose places on the tip are identified with the chain).  Why: a rotation error of the
frame moves those points by the lever times the angle, so the one forward model, its point Jacobian and every fit
take orientations with no second model; the residual is a distance between points, never a difference of
roll-pitch-yaw angles (which jumps by 360 deg across +-180 deg).  The two points' covariance is the point's plus
(lever x angle noise)^2 per axis; the correlation with the row's own point is neglected.  A row stays one pose: the
counts, the outlier report and the held-out split are about rows.

Orientation errors are reported as the geodesic angle between the measured and the predicted frame
(:func:`geodesic_deg`): the predicted frame is the one the model's three points of the row span.
"""
from __future__ import annotations

import numpy as np

from .errors import RobocalError
from .rows import point_covariance, predict_rows
from .targets import reference_name

LEVER_MM = 100.0
DEFAULT_NOISE_DEG = 0.01
#: the targets a 6-D row adds, per axis of the measured frame
AXES = (("@x", 0), ("@y", 1))
CONVENTION = "rx_deg..rz_deg: the measured frame in the instrument frame, R = Rz(rz) Ry(ry) Rx(rx)"


def rotations(rpy_rad: np.ndarray) -> np.ndarray:
    """(N, 3, 3) ``Rz(rz) Ry(ry) Rx(rx)`` for rows of (rx, ry, rz) in radians."""
    rx, ry, rz = np.asarray(rpy_rad, float).T
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    R = np.empty((len(rx), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx
    R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx
    R[:, 2, 0], R[:, 2, 1], R[:, 2, 2] = -sy, cy * sx, cy * cx
    return R


def frames_from_points(p: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """(N, 3, 3) the frame three points span: x towards ``px``, y towards ``py`` made orthogonal, z = x cross y."""
    x = px - p
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = py - p
    y -= np.einsum("ni,ni->n", y, x)[:, None] * x
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=2)


def geodesic_deg(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """(N,) the angle of the rotation taking each ``Ra`` to ``Rb`` (deg): the geodesic distance on SO(3), which
    wraps by itself (rz = 179.9 and -179.9 are 0.2 deg apart)."""
    # ||Ra - Rb|| (Frobenius) = 2 sqrt(2) sin(angle / 2): exact also for the small angles that matter here, where
    # the arccos of the trace loses half the digits
    s = np.linalg.norm(np.asarray(Ra) - np.asarray(Rb), axis=(-2, -1)) / (2.0 * np.sqrt(2.0))
    return np.degrees(2.0 * np.arcsin(np.clip(s, 0.0, 1.0)))


def summary_deg(err_deg: np.ndarray) -> dict:
    """``n``, ``mean_deg``, ``rms_deg``, ``p95_deg``, ``max_deg`` of geodesic errors."""
    e = np.asarray(err_deg, float)
    if e.size == 0:
        return {"n": 0, "mean_deg": None, "rms_deg": None, "p95_deg": None, "max_deg": None}
    return {"n": int(e.size), "mean_deg": float(e.mean()), "rms_deg": float(np.sqrt(np.mean(e ** 2))),
            "p95_deg": float(np.percentile(e, 95)), "max_deg": float(e.max())}


def statement(noise_deg: float) -> str:
    """The one line that says how orientations were used (terminal and JSON)."""
    return (f"{CONVENTION}; 1 sigma {noise_deg:g} deg per axis; each row fitted as its point and two points "
            f"{LEVER_MM:g} mm along the measured x and y axes; errors are geodesic angles")


def dropped_note(source) -> str:
    """What a command that compares positions only says about 6-D rows (one line)."""
    return (f"{source}: rx_deg, ry_deg, rz_deg dropped: the diagnosis compares positions only (identify and "
            "evaluate use the orientations)")


def with_orientation_points(table, robot, noise_mm: float, sigma_angle_rad: float, lever_mm: float = LEVER_MM):
    """The table whose 6-D rows also carry their two axis points (targets ``T@x``, ``T@y``; see the module
    docstring) and the robot with those tool points; the table and the robot as they are without orientations."""
    if table.orientation_rad is None:
        return table, robot
    if table.points_mm is None:
        raise RobocalError(f"{table.source}: rx_deg, ry_deg, rz_deg need x, y, z (the point of the measured frame)")
    names = table.target or [reference_name(list(robot.tool_points_mm) or ["P"])] * table.n
    if not robot.tool_points_mm:
        robot = robot.with_tool({"P": robot.tool_point()})
    R = rotations(table.orientation_rad)
    cov = point_covariance(table)
    if cov is None:
        cov = np.broadcast_to(np.eye(3) * noise_mm ** 2, (table.n, 3, 3)).copy()
    points, targets, covs = [table.points_mm], list(names), [cov]
    tool = dict(robot.tool_points_mm)
    for suffix, axis in AXES:
        points.append(table.points_mm + lever_mm * R[:, :, axis])
        targets += [n + suffix for n in names]
        covs.append(cov + np.eye(3) * (lever_mm * sigma_angle_rad) ** 2)
        for n in dict.fromkeys(names):
            tool.setdefault(n + suffix, tool[n] + lever_mm * np.eye(3)[axis])
    out = table.subset(np.concatenate([np.arange(table.n)] * (1 + len(AXES))))
    out.points_mm, out.target, out.cov_mm2 = np.concatenate(points), targets, np.concatenate(covs)
    out.orientation_rad = None
    return out, robot.with_tool(tool)


def axis_points(model, theta: np.ndarray, table, new_stations: bool = False) -> list[np.ndarray] | None:
    """The model's predictions (N, 3) of each 6-D row's point and its two axis points (the frame the model predicts
    for the row spans them); None when the table has no orientations or the model was fitted to none."""
    if table.orientation_rad is None:
        return None
    names = table.target or [reference_name(list(model.robot.tool_points_mm) or ["P"])] * table.n
    tool = model.robot.tool_points_mm
    if not all(n + s in tool for n in set(names) for s, _ in AXES):
        return None
    out = []
    for suffix in [""] + [s for s, _ in AXES]:
        sub = table.subset(np.arange(table.n))
        sub.target = [n + suffix for n in names]
        out.append(predict_rows(model, theta, sub, new_stations))
    return out


def orientation_errors_deg(model, theta: np.ndarray, table, new_stations: bool = False) -> np.ndarray | None:
    """(N,) geodesic angle (deg) between each 6-D row's measured frame and the frame the model predicts for it;
    None when there is nothing to compare (:func:`axis_points`)."""
    pts = axis_points(model, theta, table, new_stations)
    return None if pts is None else geodesic_deg(rotations(table.orientation_rad), frames_from_points(*pts))
