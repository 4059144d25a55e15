"""The calibration description: a TOML file that wraps a URDF with what a calibration needs beyond the URDF.

Example (``examples/tiago_mocap.toml``)::

    urdf = "tiago_no_hand.urdf"          # relative to this file
    base_link = "base_footprint"         # optional: default the URDF root
    tip_link = "arm_7_link"              # optional: default the only moving leaf

    [tool.points]                        # named points on the tip link, mm (the CSV's ``target`` names one)
    marker1 = [0.0, 0.0, 0.0]

    [base]                               # optional: the base link in the measurement frame (default: identity)
    xyz_mm = [0, 0, 0]
    rpy_deg = [0, 0, 0]

    [masses.arm_3_link]                  # optional: replaces the URDF inertial of that link (frame of the link)
    mass_kg = 1.5
    com_mm = [10, 0, 5]

    [drives.arm_1_joint]                 # optional, only where encoders are read
    gear_ratio = 100.0
    encoder_counts_per_rev = 4096

    [tolerances]                         # 1-sigma priors for identification: parameter or JOINT.param names,
    "arm_2_joint.a_mm" = 0.5             # lengths in mm, angles in degrees (``*_deg``)
    "base.z_mm" = 20.0

    [readings]                           # reading conventions: the controller's readings, in order
    names = ["J1", "J2", "J3"]
    [readings.joints]                    # joint = linear combination of readings (+ offset_deg / offset_mm)
    j3 = { J2 = 1.0, J3 = 1.0 }          # e.g. a J3 measured from the horizontal
    passive = { J1 = -1.0, J2 = -1.0, offset_deg = 0.0 }

A joint with no entry in ``[readings.joints]`` is the reading of the same name.  Without ``[readings]`` the readings
are the URDF's moving, non-mimic joints.  A purely kinematic calibration needs none of the optional tables.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from .tomlspec import Checker, Field
from .units import DEG

TOP_SPEC = {
    "urdf": Field("str", required=True),
    "name": Field("str", default=""),
    "base_link": Field("str", default=""),
    "tip_link": Field("str", default=""),
    "tool": Field("table", default={}),
    "base": Field("table", default={}),
    "masses": Field("table", default={}),
    "drives": Field("table", default={}),
    "tolerances": Field("table", default={}),
    "readings": Field("table", default={}),
}
BASE_SPEC = {
    "xyz_mm": Field("vector", default=[0.0, 0.0, 0.0], length=3),
    "rpy_deg": Field("vector", default=[0.0, 0.0, 0.0], length=3, min=-360, max=360),
}
MASS_SPEC = {"mass_kg": Field("number", required=True, min=0.0), "com_mm": Field("vector", default=[0.0, 0.0, 0.0],
                                                                                    length=3)}
DRIVE_SPEC = {"gear_ratio": Field("number", required=True),
              "encoder_counts_per_rev": Field("int", required=True, positive=True)}


def build_description(chk: Checker, data: dict, path: Path, base_link: str | None = None,
                      tip_link: str | None = None):
    """The :class:`calib.robot.Robot` a calibration description defines (command-line cut wins over the file's)."""
    from .robot import Robot, _rpy_matrix, rpy_from_matrix
    from .urdf import analyse_chain, parameter_meaning, read_urdf

    top = chk.table(data, TOP_SPEC, "")
    urdf_path = (path.parent / top["urdf"]) if not Path(top["urdf"]).is_absolute() else Path(top["urdf"])
    if not urdf_path.exists():
        chk.fail("urdf", f"file {str(urdf_path)!r} not found")
    tree = read_urdf(urdf_path)
    for link, table in _tables(chk, top["masses"], "masses").items():
        if link not in tree.links:
            chk.fail(f"masses.{link}", f"is not a link of {urdf_path.name} (links: {', '.join(tree.links)})")
        m = chk.table(table, MASS_SPEC, f"masses.{link}")
        tree.links[link].mass_kg = float(m["mass_kg"])
        tree.links[link].com_m = np.asarray(m["com_mm"], float) / 1000.0
    ch = analyse_chain(tree, base_link or top["base_link"] or None, tip_link or top["tip_link"] or None)
    names = [j.name for j in ch.axes]
    n = len(names)

    tool = top["tool"]
    if not isinstance(tool, dict) or set(tool) - {"points"}:
        chk.fail("tool", "only [tool.points] is known")
    points = {k: np.asarray(chk.value(v, Field("vector", length=3), f"tool.points.{k}"), float)
              for k, v in (tool.get("points") or {}).items()}
    T = ch.tip_in_frame_n
    tool_n = {k: T[:3, :3] @ v + T[:3, 3] for k, v in (points or {ch.tip_link: np.zeros(3)}).items()}

    base = chk.table(top["base"], BASE_SPEC, "base")
    B = np.eye(4)
    B[:3, :3] = _rpy_matrix(np.asarray(base["rpy_deg"], float) * DEG)
    B[:3, 3] = base["xyz_mm"]
    F0 = ch.frame0_in_base
    W0 = B @ F0                                                       # frame 0 in the measurement frame

    gear, counts = np.ones(n), np.full(n, 2.0 ** 20)
    for joint, table in _tables(chk, top["drives"], "drives").items():
        if joint not in names:
            chk.fail(f"drives.{joint}", f"is not a moving joint of the chain ({', '.join(names)})")
        d = chk.table(table, DRIVE_SPEC, f"drives.{joint}")
        if d["gear_ratio"] == 0:
            chk.fail(f"drives.{joint}.gear_ratio", "must not be zero")
        gear[names.index(joint)] = d["gear_ratio"]
        counts[names.index(joint)] = d["encoder_counts_per_rev"]

    rnames, M, off = _readings(chk, top["readings"], ch)
    pris = np.array([j.type == "prismatic" for j in ch.axes])
    L = ch.links
    robot = Robot(
        name=top["name"] or f"{tree.name} ({ch.base_link} -> {ch.tip_link})",
        a_mm=np.array([x.a for x in L]), d_mm=np.array([x.d for x in L]), alpha_rad=np.array([x.alpha for x in L]),
        theta_offset_rad=np.array([x.theta for x in L]), beta_rad=np.array([x.beta for x in L]),
        hayati=np.array([x.hayati for x in L], bool), limits_rad=ch.limits, gear_ratio=gear, counts_per_rev=counts,
        mass_kg=ch.mass_kg, com_mm=ch.com_mm, coupling=np.eye(n),
        gravity_m_s2=W0[:3, :3].T @ (B[:3, :3] @ np.array([0.0, 0.0, -9.80665])),
        base_xyz_mm=W0[:3, 3].copy(), base_rpy_rad=rpy_from_matrix(W0[:3, :3]), tool_points_mm=tool_n,
        joint_names=tuple(names), source=chk.source, prismatic=pris, frame0_in_base=F0,
        reading_names=tuple(rnames), reading_matrix=M, reading_offset=off, param_meaning=parameter_meaning(ch),
    )
    return replace(robot, tolerances=_tolerances(chk, top["tolerances"], robot))


def _tables(chk: Checker, t: dict, where: str) -> dict:
    if not isinstance(t, dict):
        chk.fail(where, "must be a table")
    for k, v in t.items():
        if not isinstance(v, dict):
            chk.fail(f"{where}.{k}", "must be a table")
    return t


def _readings(chk: Checker, t: dict, ch) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Reading names and the map joint = M @ reading + offset (internal units)."""
    if not t:
        return list(ch.readings), ch.reading_matrix, ch.reading_offset
    if not isinstance(t, dict) or set(t) - {"names", "joints"}:
        chk.fail("readings", "only names = [...] and [readings.joints] are known")
    names = t.get("names")
    if not isinstance(names, list) or not names or not all(isinstance(s, str) for s in names):
        chk.fail("readings.names", "must be a list of reading names")
    if len(set(names)) != len(names):
        chk.fail("readings.names", "a reading name appears twice")
    joints = _tables(chk, t.get("joints", {}), "readings.joints")
    axes = [j.name for j in ch.axes]
    n = len(axes)
    for joint, combo in joints.items():
        if joint not in axes:
            chk.fail(f"readings.joints.{joint}", f"is not a moving joint of the chain ({', '.join(axes)})")
        for rd in combo:
            if rd not in names and rd not in ("offset_deg", "offset_mm"):
                chk.fail(f"readings.joints.{joint}.{rd}", f"reading {rd!r} is not one of the readings ({', '.join(names)})")
    M, off = np.zeros((n, len(names))), np.zeros(n)
    for k, name in enumerate(axes):
        pris = ch.axes[k].type == "prismatic"
        if name in joints:
            for rd, c in joints[name].items():
                key = f"readings.joints.{name}.{rd}"
                if rd in ("offset_deg", "offset_mm"):
                    if (rd == "offset_mm") != pris:
                        chk.fail(key, f"{name} is {'prismatic: use offset_mm' if pris else 'revolute: use offset_deg'}")
                    off[k] = chk.value(c, Field("number"), key) * (1.0 if pris else DEG)
                    continue
                M[k, names.index(rd)] = chk.value(c, Field("number"), key)
        elif name in names:
            M[k, names.index(name)] = 1.0
        elif ch.axes[k].mimic is not None:
            M[k] = 0.0
            src = np.flatnonzero(ch.reading_matrix[k])
            for s in src:
                followed = ch.readings[s]
                if followed not in names:
                    chk.fail("readings", f"{name} mimics {followed}, which is neither a reading nor defined in "
                                         "[readings.joints]")
                M[k, names.index(followed)] = ch.reading_matrix[k, s]
            off[k] = ch.reading_offset[k]
        else:
            chk.fail("readings.joints", f"joint {name} is neither a reading nor given as a combination of readings")
    return names, M, off


def _tolerances(chk: Checker, t: dict, robot) -> dict[str, float]:
    """Priors by kinematic parameter name (``j2.a_mm``, ``base.z_mm``) or by joint name (``arm_1_joint.a_mm``);
    ``*_deg`` keys are converted to the ``*_rad`` parameter (names as :func:`calib.priors.canonical` reads them)."""
    from .errors import RobocalError
    from .kinematics import Kinematics
    from .priors import canonical

    known = set(Kinematics(robot).names)
    out = {}
    for key, v in t.items():
        sd = chk.value(v, Field("number", positive=True), f"tolerances.{key}")
        try:
            name, scale = canonical(key, robot, known)
        except RobocalError:
            chk.fail(f"tolerances.{key}", f"is not a parameter of the chain (e.g. j1.a_mm, "
                                          f"{robot.joint_names[0]}.alpha_deg, base.z_mm, tool.x_mm)")
        out[name] = float(sd) * scale
    return out
