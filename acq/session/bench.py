"""The bench for any robot: the robot-dependent entries of a set-up, from the robot's description and profile
(:mod:`calib.profile`).

The thesis's cell (:func:`acq.session.setup.standard_setup`) is the Puma's: its loads, its link, point P.  For any
other robot the same instruments, ruler and targets are kept and the rest comes from the description at the
profile's reference pose:

* the base placed so that the arm at its reference pose stands :data:`DEPTH_MM` in front of the middle of the
  theodolites' baseline, its centre :data:`HEIGHT_MM` above their horizon;
* joint compliance on the (at most two) most proximal joints whose axis is level at the reference pose (a weight
  turns nothing about a vertical axis), a mass hung :data:`LEVER_MM` from the axis, level across it, on that link;
* link compliance on the longest link across its joint's axis (at least :data:`MIN_BEAM_MM`), dial gauges and the
  load at fixed shares of its length;
* no point P (eq 4.3.15's d3 is the thesis Puma's).
"""
from __future__ import annotations

import json

import numpy as np

from calib.model import MeasurementModel
from calib.profile import RobotProfile, profile_of
from calib.robot import Robot
from calib.units import DEG

from .setup import frame_point, lever_point, standard_setup, theta_with_base, up_direction

DEPTH_MM = 2850.0
HEIGHT_MM = 300.0
LEVER_MM = 500.0
#: an axis within this of level takes a load (deg)
LEVEL_DEG = 30.0
COMPLIANCE_LOADS_N = [0, 10, 20, 30, 45, 60, 75]
MIN_BEAM_MM = 300.0
GAUGE_SHARES = (0.25, 0.45, 0.65)
LOAD_SHARE = 0.7
LINK_LOADS_N = [0, 50, 100, 150]


def _ready_chain(robot: Robot, profile: RobotProfile, base_xyz_mm) -> tuple[MeasurementModel, object]:
    model = MeasurementModel(robot)
    th = theta_with_base(model, base_xyz_mm)
    q = np.asarray(profile.ready_deg, float) * robot.edge_scale
    return model, model.kin.forward(q[None], th[: model.n_geometric])


def placed_base(robot: Robot, profile: RobotProfile, baseline_mm: float) -> list[float]:
    """Robot frame 0 in the measurement frame: the centre of the arm's frames at the reference pose
    :data:`DEPTH_MM` in front of the middle of the baseline and :data:`HEIGHT_MM` above the instruments."""
    _, fp = _ready_chain(robot, profile, (0.0, 0.0, 0.0))
    c = fp.frame_t[0].mean(axis=0)
    return [round(float(v), 0) for v in np.array([baseline_mm / 2, DEPTH_MM, HEIGHT_MM]) - c]


def compliance_entries(robot: Robot, profile: RobotProfile, base_xyz_mm) -> dict:
    """Joint-compliance entries (see the module docstring), in the set-up's vocabulary."""
    _, fp = _ready_chain(robot, profile, base_xyz_mm)
    up = up_direction(fp, robot)
    out = {}
    for j in profile.sweep_joints:
        z = fp.joint_axis[0, j - 1]
        if abs(float(z @ up)) > np.sin(LEVEL_DEG * DEG) or len(out) == 2:
            continue
        p = lever_point(fp, j, LEVER_MM, 0.0, up)
        out[str(j)] = {"link": j, "point_mm": frame_point(fp, j, p), "loads_n": list(COMPLIANCE_LOADS_N),
                       "pose_deg": list(profile.ready_deg)}
    return out


def link_entry(robot: Robot, profile: RobotProfile, base_xyz_mm) -> dict | None:
    """The link-compliance entry on the longest beam (see the module docstring); None when no link is long
    enough."""
    _, fp = _ready_chain(robot, profile, base_xyz_mm)
    lengths = {j: float(np.linalg.norm(np.subtract(*fp.link_beam(j))[0])) for j in profile.sweep_joints
               if abs(robot.a_mm[j - 1]) >= MIN_BEAM_MM}          # a beam across its joint's axis
    if not lengths:
        return None
    j, L = max(lengths.items(), key=lambda kv: kv[1])
    return {"joint": j, "gauges_x_mm": [round(s * L, 1) for s in GAUGE_SHARES], "load_x_mm": round(LOAD_SHARE * L, 1),
            "loads_n": list(LINK_LOADS_N), "second_moment_mm4": None, "pose_deg": list(profile.ready_deg)}


def robot_setup(robot: Robot, base: dict | None = None) -> dict:
    """A set-up for ``robot``: ``base`` (default :func:`acq.session.setup.standard_setup`) with the reference pose
    of the robot's profile; for a robot other than the thesis's Puma, its base, loads and link from its description
    (see the module docstring) in place of the thesis cell's, and no point P."""
    profile = profile_of(robot)
    setup = json.loads(json.dumps(base)) if base is not None else standard_setup()
    setup["reference_pose_deg"] = list(profile.ready_deg)
    if profile.thesis:
        return setup
    setup.pop("point_p", None)
    setup["base_xyz_mm"] = placed_base(robot, profile, float(setup["stations"]["L_mm"]))
    setup["base_rpy_deg"] = [0.0, 0.0, 0.0]
    setup["compliance"] = compliance_entries(robot, profile, setup["base_xyz_mm"])
    link = link_entry(robot, profile, setup["base_xyz_mm"])
    if link is None:
        setup.pop("link", None)
    else:
        setup["link"] = link
    return setup
