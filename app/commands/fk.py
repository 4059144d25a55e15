"""``robocal fk``: the tool point in the robot base frame for joint readings in degrees."""
from __future__ import annotations

import json
import math

import numpy as np

from calib.errors import RobocalError
from calib.kinematics import Kinematics
from calib.angles import rpy_from_matrix
from calib.loading import load_robot
from acq.argtypes import add_robot_argument

NAME = "fk"
HELP = ("tool point (mm, robot base frame) for joint readings in degrees (mm for prismatic joints); every point of a "
        "robot with several (a branched robot's hands)")
EXAMPLES = """\
robocal fk 0 -90 90 0 0 0 --json                 # tool point of the Puma 560 at READY
robocal fk 10 -40 70 30 -20 50 --robot my_robot.urdf --tip-link tool0
"""


def add_arguments(p):
    p.add_argument("q", nargs="+", metavar="Q",
                   help="joint readings in degrees (theta_j of the A-matrices; mm for a prismatic joint)")
    add_robot_argument(p)
    p.add_argument("--json", action="store_true", help='print {"x_mm": .., "y_mm": .., "z_mm": ..}')


def run(args) -> int:
    from calib.names import reading_label
    robot = load_robot(args.robot)
    if len(args.q) != robot.n_readings:
        raise RobocalError(f"fk: expected {robot.n_readings} joint readings for {robot.name} "
                           f"({', '.join(robot.reading_names)}), got {len(args.q)}")
    q = []
    for i, text in enumerate(args.q, 1):
        try:
            v = float(text)
        except ValueError:
            raise RobocalError(f"fk: {reading_label(robot, i)} reading {text!r} is not a number "
                               f"({'mm' if robot.reading_prismatic[i - 1] else 'degrees'})") from None
        if not math.isfinite(v):
            raise RobocalError(f"fk: {reading_label(robot, i)} reading {text!r} is not finite")
        q.append(v)
    theta = robot.joints_from_readings(np.array([q]) * robot.reading_edge_scale)
    robot.check_readings(theta / robot.edge_scale, "fk")
    kin = Kinematics(robot)
    # the description's own base frame (frame 0 of a DH description, a URDF's base link), whatever the base pose in
    # the measurement frame
    params = kin.nominal.copy()
    F0 = robot.frame0_in_base
    base = [*F0[:3, 3], *rpy_from_matrix(F0[:3, :3])[::-1]]
    params[[kin.index[f"base.{k}"] for k in ("x_mm", "y_mm", "z_mm", "yaw_rad", "pitch_rad", "roll_rad")]] = base
    points = {name: kin.forward(theta, kin.params_with_tool(xyz, params), robot.point_frame(name)).point[0]
              for name, xyz in robot.tool_points_mm.items()} or {"tool": kin.points(theta, params)[0]}
    ref = robot.reference_point_name() or "tool"
    x, y, z = points[ref]
    if args.json:
        out = {"x_mm": round(float(x), 6), "y_mm": round(float(y), 6), "z_mm": round(float(z), 6)}
        if len(points) > 1:         # several points (a branched robot's hands): every one, the reference above
            out["points"] = {k: {c: round(float(v), 6) for c, v in zip(("x_mm", "y_mm", "z_mm"), p)}
                             for k, p in points.items()}
        print(json.dumps(out))
    elif len(points) > 1:
        for k, (px, py, pz) in points.items():
            print(f"{k}: x_mm = {px:.3f}  y_mm = {py:.3f}  z_mm = {pz:.3f}")
    else:
        print(f"x_mm = {x:.3f}\ny_mm = {y:.3f}\nz_mm = {z:.3f}")
    return 0
