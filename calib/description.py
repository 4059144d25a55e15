"""The calibration description: a TOML file that wraps a URDF with what a calibration needs beyond the URDF.

Example (``examples/tiago_mocap.toml``)::

    urdf = "tiago_no_hand.urdf"          # relative to this file
    base_link = "base_footprint"         # optional: default the URDF root
    tip_link = "arm_7_link"              # optional: default the only moving leaf

    [tool.points]                        # named points on the tip link, mm (the CSV's ``target`` names one)
    marker1 = [0.0, 0.0, 0.0]
    left_hand = { link = "arm_left_7_link", xyz_mm = [0, 0, 50] }     # a point on a link of its own

    [joints.coupled]                     # joints held at a linear combination of others (no data column)
    torso_3_joint = { torso_1_joint = -1.0, torso_2_joint = -1.0, offset_deg = 0.0 }

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
are the URDF's moving, non-mimic joints (and any joint a mimic joint follows from off the robot's tree).  A purely
kinematic calibration needs none of the optional tables.

Branched robots: with points on several links (``{ link = ..., xyz_mm = ... }``) ``tip_link`` may be omitted; the
robot is then the tree from ``base_link`` to every link that carries a point, and the joints several paths share
(a torso under two arms) are one set of parameters.  A point given as a bare ``[x, y, z]`` is on ``tip_link``.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from .angles import rpy_matrix
from .errors import RobocalError
from .kinematics import Kinematics
from .priors import canonical
from .tomlspec import Checker, Field
from .units import DEG
from .urdf import analyse_tree, check_link, cut_chain, read_urdf, robot_from_analysis

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
    "joints": Field("table", default={}),
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
    base = base_link or top["base_link"] or None
    tip = tip_link or top["tip_link"] or None
    if tip is not None:
        check_link(tree, tip, "tip")
    raw = _tool_points(chk, top["tool"], tree, urdf_path.name)
    if tip is None and (not raw or any(link is None for link, _ in raw.values())):
        base, tip, _ = cut_chain(tree, base, None)          # the only moving leaf, or an error naming them
    points = {k: (link or tip, xyz) for k, (link, xyz) in raw.items()} or {tip: (tip, np.zeros(3))}
    point_links = list(dict.fromkeys(link for link, _ in points.values()))
    ch = analyse_tree(tree, base, point_links)
    axes = [j.name for j in ch.axes]
    n = len(axes)

    place = chk.table(top["base"], BASE_SPEC, "base")
    B = np.eye(4)
    B[:3, :3] = rpy_matrix(np.asarray(place["rpy_deg"], float) * DEG)
    B[:3, 3] = place["xyz_mm"]

    gear, counts = np.ones(n), np.full(n, 2.0 ** 20)
    for joint, table in _tables(chk, top["drives"], "drives").items():
        if joint not in axes:
            chk.fail(f"drives.{joint}", f"is not a moving joint of the robot ({', '.join(dict.fromkeys(axes))})")
        d = chk.table(table, DRIVE_SPEC, f"drives.{joint}")
        if d["gear_ratio"] == 0:
            chk.fail(f"drives.{joint}.gear_ratio", "must not be zero")
        for k in (k for k, a in enumerate(axes) if a == joint):
            gear[k], counts[k] = d["gear_ratio"], d["encoder_counts_per_rev"]

    rnames, M, off = _readings(chk, top["readings"], ch)
    rnames, M, off = _coupled(chk, top["joints"], ch, rnames, M, off)
    robot = robot_from_analysis(ch, points, source=chk.source, name=top["name"], base_in_world=B, gear_ratio=gear,
                                counts_per_rev=counts, reading_names=tuple(rnames), reading_matrix=M,
                                reading_offset=off)
    return replace(robot, tolerances=_tolerances(chk, top["tolerances"], robot))


def _tool_points(chk: Checker, tool, tree, urdf_name: str) -> dict[str, tuple[str | None, np.ndarray]]:
    """``[tool.points]``: name -> (link or None for the tip link, xyz in that link's frame, mm)."""
    if not isinstance(tool, dict) or set(tool) - {"points"}:
        chk.fail("tool", "only [tool.points] is known")
    out = {}
    for k, v in (tool.get("points") or {}).items():
        key = f"tool.points.{k}"
        if isinstance(v, dict):
            if set(v) - {"link", "xyz_mm"} or "link" not in v:
                chk.fail(key, 'must be [x, y, z] (mm, on tip_link) or { link = "LINK", xyz_mm = [x, y, z] }')
            link = v["link"]
            if not isinstance(link, str) or link not in tree.links:
                chk.fail(f"{key}.link", f"{link!r} is not a link of {urdf_name}")
            xyz = chk.value(v.get("xyz_mm", [0.0, 0.0, 0.0]), Field("vector", length=3), f"{key}.xyz_mm")
            out[k] = (link, np.asarray(xyz, float))
        else:
            out[k] = (None, np.asarray(chk.value(v, Field("vector", length=3), key), float))
    return out


def _coupled(chk: Checker, t: dict, ch, names: list[str], M: np.ndarray, off: np.ndarray):
    """``[joints.coupled]``: ``JOINT = { OTHER = factor, ..., offset_deg | offset_mm = c }`` -- a passive or coupled
    joint held at a linear combination of other joints (edge units: degrees, mm).  Its reading column is replaced by
    that combination everywhere (its own links, the mimic joints following it), so the data need not carry it."""
    if not t:
        return names, M, off
    if not isinstance(t, dict) or set(t) - {"coupled"}:
        chk.fail("joints", "only [joints.coupled] is known")
    coupled = _tables(chk, t.get("coupled", {}), "joints.coupled")
    by_name = {j.name: j for j in ch.axes if j.type != "fixed"}
    own = {}
    for k, j in enumerate(ch.axes):
        own.setdefault(j.name, k)

    def scale(j):                                        # internal units per edge unit
        return 1.0 if j.type == "prismatic" else DEG

    deps = {}
    for joint, combo in coupled.items():
        where = f"joints.coupled.{joint}"
        if joint not in by_name:
            chk.fail(where, f"is not a moving joint of the robot ({', '.join(by_name)})")
        if joint not in names:
            chk.fail(where, "is not a reading: it is already given by a mimic tag or [readings.joints]")
        deps[joint] = []
        for other in combo:
            if other in ("offset_deg", "offset_mm"):
                continue
            if other == joint:
                chk.fail(f"{where}.{other}", "a joint cannot be coupled to itself")
            if other not in by_name:
                chk.fail(f"{where}.{other}", f"is not a moving joint of the robot ({', '.join(by_name)})")
            deps[joint].append(other)
    order, state = [], {}

    def visit(j, trail):
        if state.get(j) == 1:
            chk.fail(f"joints.coupled.{j}", "the couplings form a cycle (" + " -> ".join(trail + [j]) + ")")
        if state.get(j) == 2 or j not in deps:
            return
        state[j] = 1
        for d in deps[j]:
            visit(d, trail + [j])
        state[j] = 2
        order.append(j)
    for j in deps:
        visit(j, [])
    M, off = M.copy(), off.copy()
    for joint in order:
        c = names.index(joint)
        jt = by_name[joint]
        g, h = np.zeros(len(names)), 0.0
        for other, f in coupled[joint].items():
            key = f"joints.coupled.{joint}.{other}"
            if other in ("offset_deg", "offset_mm"):
                pris = jt.type == "prismatic"
                if (other == "offset_mm") != pris:
                    chk.fail(key, f"{joint} is {'prismatic: use offset_mm' if pris else 'revolute: use offset_deg'}")
                h += chk.value(f, Field("number"), key) * scale(jt)
                continue
            factor = chk.value(f, Field("number"), key) * scale(jt) / scale(by_name[other])
            g += factor * M[own[other]]
            h += factor * off[own[other]]
        # the joint's reading, everywhere it appears, becomes the combination
        coef = M[:, c].copy()
        M += np.outer(coef, g)
        off += coef * h
        M[:, c] = 0.0
    keep = [k for k, nm in enumerate(names) if nm not in coupled]
    return [names[k] for k in keep], M[:, keep], off


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
    moving = [a for a, j in zip(axes, ch.axes) if j.type != "fixed"]
    for joint, combo in joints.items():
        if joint not in moving:
            chk.fail(f"readings.joints.{joint}", f"is not a moving joint of the robot ({', '.join(dict.fromkeys(moving))})")
        for rd in combo:
            if rd not in names and rd not in ("offset_deg", "offset_mm"):
                chk.fail(f"readings.joints.{joint}.{rd}", f"reading {rd!r} is not one of the readings ({', '.join(names)})")
    M, off = np.zeros((n, len(names))), np.zeros(n)
    for k, name in enumerate(axes):
        pris = ch.axes[k].type == "prismatic"
        if ch.axes[k].type == "fixed":
            continue
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
