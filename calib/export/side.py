"""The side file of a calibrated URDF: what the calibration found that a URDF cannot hold, in one JSON document.

A URDF holds a tree of rigid links and ideal joints.  It has no place for where the robot stood in the instrument's
frame (the base link's pose), for the measured points on the tool, for how the controller's readings map onto the
joints (reading conventions: an encoder whose zero is not the joint's, a joint driven by a combination of readings),
nor for anything that is not rigid geometry: compliance, transmission error, backlash, cross coupling, thermal
drift.  Those go here, with their 1-sigma errors, so that nothing the fit found is silently dropped.
"""
from __future__ import annotations

import numpy as np

from .. import names as naming
from ..units import DEG
from .frames import rpy_of

FORMAT = "robocal-urdf-side/1"
#: effects that are not the robot's: where the targets sit (written as tool points) and the instrument set-ups
_NOT_ROBOT = ("target_offset", "station_offset")


def side_document(model, theta: np.ndarray, sigma: np.ndarray, corr, urdf_name: str, made_from: str,
                  base_link: str, check: dict, urdf_readings: np.ndarray | None = None) -> dict:
    """The side file's content (see the module docstring); ``sigma`` is the 1-sigma error per model parameter;
    ``urdf_readings`` the reading map the URDF's own mimic joints make (the written file holds that one)."""
    robot = model.robot
    B = corr.base_in_measurement
    doc: dict = {
        "format": FORMAT, "urdf": urdf_name, "made_from": made_from,
        "base_link": base_link, "tip_link": corr.tip_link,
        "base_link_in_measurement_frame": {"xyz_mm": [float(v) for v in B[:3, 3]],
                                           "rpy_deg": [float(v) for v in rpy_of(B[:3, :3]) / DEG],
                                           "convention": "URDF roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)"},
        "tool_points": {k: {"link": corr.point_links.get(k, corr.tip_link), "xyz_mm": [float(v) for v in p]}
                        for k, p in corr.tool_points_on_links.items()},
    }
    own = urdf_readings is not None and np.shape(urdf_readings) == np.shape(robot.reading_matrix) \
        and np.allclose(urdf_readings, robot.reading_matrix) and not np.any(robot.reading_offset)
    if not robot.readings_are_joints and not own:
        doc["readings"] = {"names": list(robot.reading_names), "joints": list(robot.joint_names),
                           "matrix": np.asarray(robot.reading_matrix).tolist(),
                           "offset": [float(v) for v in robot.reading_offset / robot.edge_scale],
                           "convention": "joint = matrix @ reading + offset (deg, mm for a prismatic joint)"}
    if not np.allclose(robot.coupling, np.eye(robot.n)):
        doc["motor_coupling"] = {"matrix": np.asarray(robot.coupling).tolist(),
                                 "convention": "motor = diag(gear_ratio) (matrix @ joint)"}
    effects = []
    for e, sl in zip(model.effects, model.effect_slices):
        if e.kind in _NOT_ROBOT:
            continue
        params = {}
        for name, i in zip(e.param_names, range(sl.start, sl.stop)):
            unit, scale = naming.edge_unit(naming.unit_of(name))
            params[naming.edge_name(name, robot)] = {"value": float(theta[i]) / scale, "sigma": float(sigma[i]) / scale,
                                              "unit": unit}
        effects.append({"kind": e.kind, "joint": e.joint,
                        "joint_name": naming.joint_name(robot, e.joint) if e.joint else None,
                        "label": naming.effect_label(robot, e), "parameters": params})
    if effects:
        doc["effects"] = effects
    doc["check"] = check
    return doc


def not_in_urdf(doc: dict) -> str:
    """The side file's content as one line (what the terminal says beside the written URDF)."""
    on = {}
    for k, v in doc["tool_points"].items():
        on.setdefault(v["link"], []).append(k)
    items = [f"{doc['base_link']} pose in the measurement frame"] + \
        [f"tool point{'s' if len(ks) > 1 else ''} {', '.join(ks)} on {link}" for link, ks in on.items()]
    if "readings" in doc:
        items.append("reading conventions (joint = matrix @ reading + offset)")
    if "motor_coupling" in doc:
        items.append("motor coupling matrix")
    items += [e["label"] for e in doc.get("effects", [])]
    return "; ".join(items)
