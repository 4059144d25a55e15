"""URDF robot descriptions: a chain of a URDF tree, or the tree from its base to several links, as a robocal
:class:`calib.robot.Robot`.

The URDF's kinematic and mass elements are read with lxml (:func:`read_urdf` says why); this module cuts the tree and
maps it onto the links robocal identifies (:mod:`calib.kinematics`: ``Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)`` per
moving joint; on a tree, a branch link per further child of a joint, :func:`analyse_tree`).

* The chain runs from ``base_link`` (default: the root) to ``tip_link`` (default: the only *moving leaf*, the child of
  a moving joint below which nothing moves; several candidates are an error that lists them).
* Fixed joints fold into the next moving joint; joints of side branches are held at zero (their links' masses count
  for the link they hang from).  A mimic joint stays an axis of the chain, driven as ``multiplier x q + offset`` of
  the joint it follows: it is not a reading (see :attr:`Robot.reading_matrix`).
* Prismatic joints add to d (mm), continuous joints are revolute joints with +-720 deg limits.
* Every moving axis ``j`` becomes one link of the chain, with its frame ``j-1`` on that axis: standard DH (common
  normal) where consecutive axes are skew or intersecting, Hayati (``beta`` instead of ``d``) where they are within
  :data:`PARALLEL_DEG` of parallel, so the parameters are a minimal, well-conditioned set.  Frame ``n`` is frame
  ``n-1`` turned by the last joint; the tip link's origin (and any tool point given on the tip link) is the tool point
  in frame ``n``.  :func:`parameter_meaning` says which URDF quantity each parameter corrects.
* The base link's frame is the measurement frame unless the calibration description says otherwise: the robot's
  base pose is frame 0 in the base link (``Robot.frame0_in_base``), and ``robocal fk`` prints the tip in the base link.
* Inertials: each link's mass and centre of mass, summed over what moves with axis ``j`` and expressed in frame ``j``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .angles import rot_zyx, rpy_from_matrix
from .errors import RobocalError
from .kinematics import Kinematics
from .robot import Robot
from .units import DEG, G0_M_S2

PARALLEL_DEG = 1.0            # consecutive axes closer to parallel than this use the Hayati beta
MOVING = ("revolute", "continuous", "prismatic")
CONTINUOUS_LIMIT_RAD = 4 * math.pi


@dataclass
class UJoint:
    """One URDF joint, as read (SI units of the file)."""

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray                 # (4, 4) child frame at q = 0 in the parent link frame
    axis: np.ndarray                   # (3,) unit, in the joint frame
    limits: tuple[float, float] | None
    mimic: tuple[str, float, float] | None     # (followed joint, multiplier, offset)
    line: int | None = None


@dataclass
class ULink:
    name: str
    mass_kg: float
    com_m: np.ndarray                  # (3,) in the link frame


@dataclass
class UrdfTree:
    source: str
    name: str
    links: dict[str, ULink]
    joints: dict[str, UJoint]          # by name
    child_joint: dict[str, UJoint]     # link -> the joint whose child it is
    lines: dict[str, int]              # element name -> source line ("link:NAME" / "joint:NAME")

    def where(self, kind: str, name: str) -> str:
        line = self.lines.get(f"{kind}:{name}")
        return f"{self.source}: line {line}: {kind} {name!r}" if line else f"{self.source}: {kind} {name!r}"

    @property
    def root(self) -> str:
        roots = [n for n in self.links if n not in self.child_joint]
        return roots[0]

    def children(self, link: str) -> list[UJoint]:
        return [j for j in self.joints.values() if j.parent == link]


# -- reading --------------------------------------------------------------------------------------------------------
def _numbers(el, attr: str, count: int, default, where: str) -> np.ndarray:
    """``count`` numbers from an attribute (``xyz="0 0 0.1"``), the default when it is absent."""
    text = None if el is None else el.get(attr)
    if text is None:
        return np.asarray(default, float)
    try:
        v = np.array([float(x) for x in text.split()], float)
    except ValueError:
        v = np.zeros(0)
    if v.size != count or not np.all(np.isfinite(v)):
        raise RobocalError(f"{where}: {el.tag} {attr}={text!r} is not {count} finite number{'s' * (count > 1)}")
    return v


def _origin(el, where: str) -> np.ndarray:
    """A URDF ``<origin xyz rpy>`` as a 4x4 (metres): fixed-axis roll, pitch, yaw, i.e. Rz(yaw) Ry(pitch) Rx(roll)."""

    o = None if el is None else el.find("origin")
    xyz = _numbers(o, "xyz", 3, [0.0, 0.0, 0.0], where)
    r, p, y = _numbers(o, "rpy", 3, [0.0, 0.0, 0.0], where)
    return _hom(rot_zyx(y, p, r), xyz)


def read_urdf(path: str | Path) -> UrdfTree:
    """Read a URDF file's kinematic and mass elements and check it is a tree (one root, each link the child of at
    most one joint).

    Why not a URDF library: the maintained readers (yourdfpy, urdf_parser_py) load a mesh and scene stack (trimesh,
    scipy) or warn on every vendor tag, and cost a command over a second of start-up; the elements calibration reads
    -- links, inertial mass and centre, joints with origin, axis, limits, mimic -- are few and fixed by the URDF
    specification, and lxml gives each its source line for the error messages."""
    from lxml import etree      # ~20 ms at start-up (robocal fk loads this module): only a URDF file needs it

    path = Path(path)
    src = str(path)
    if not path.exists():
        raise RobocalError(f"{src}: file not found")
    try:
        root = etree.parse(str(path), etree.XMLParser(remove_comments=True, resolve_entities=False)).getroot()
    except (etree.XMLSyntaxError, OSError) as exc:
        raise RobocalError(f"{src}: not a readable URDF: {exc}") from None
    if root.tag != "robot":
        raise RobocalError(f"{src}: line {root.sourceline}: not a URDF (the root element is <{root.tag}>, not <robot>)")
    lines = {f"{el.tag}:{el.get('name')}": el.sourceline for el in root if el.tag in ("link", "joint")}
    tree = UrdfTree(src, root.get("name") or path.stem, {}, {}, {}, lines)
    for el in root.iterchildren("link"):
        name = el.get("name")
        where = tree.where("link", name)
        if not name:
            raise RobocalError(f"{src}: line {el.sourceline}: a link without a name")
        iner = el.find("inertial")
        mass_el = None if iner is None else iner.find("mass")
        mass = float(_numbers(mass_el, "value", 1, [0.0], where)[0])
        if mass < 0:
            raise RobocalError(f"{where}: inertial mass {mass:g} is negative")
        tree.links[name] = ULink(name, mass, _origin(iner, where)[:3, 3] if iner is not None else np.zeros(3))
    for el in root.iterchildren("joint"):
        name, jtype = el.get("name"), el.get("type")
        where = tree.where("joint", name)
        if not name:
            raise RobocalError(f"{src}: line {el.sourceline}: a joint without a name")
        if jtype not in MOVING + ("fixed",):
            raise RobocalError(f"{where}: joint type {jtype!r} is not supported (revolute, continuous, "
                               "prismatic, fixed)")
        parent, child = (None if el.find(k) is None else el.find(k).get("link") for k in ("parent", "child"))
        for link in (parent, child):
            if link not in tree.links:
                raise RobocalError(f"{where}: link {link!r} is not defined")
        axis = _numbers(el.find("axis"), "xyz", 3, [1.0, 0.0, 0.0], where)
        norm = float(np.linalg.norm(axis))
        if jtype in MOVING and not norm > 0:
            raise RobocalError(f"{where}: the axis is zero")
        limits = None
        lim = el.find("limit")
        if jtype in ("revolute", "prismatic") and lim is not None and lim.get("lower") is not None \
                and lim.get("upper") is not None:
            limits = (float(_numbers(lim, "lower", 1, [0.0], where)[0]), float(_numbers(lim, "upper", 1, [0.0], where)[0]))
        mimic = None
        mel = el.find("mimic")
        if mel is not None:
            mimic = (mel.get("joint"), float(_numbers(mel, "multiplier", 1, [1.0], where)[0]),
                     float(_numbers(mel, "offset", 1, [0.0], where)[0]))
        if child in tree.child_joint:
            other = tree.child_joint[child].name
            raise RobocalError(f"{where}: link {child!r} is already the child of joint {other!r}: a closed loop "
                               "(URDF describes trees)")
        uj = UJoint(name, jtype, parent, child, _origin(el, where), axis / (norm or 1.0), limits, mimic,
                    el.sourceline)
        tree.joints[name] = uj
        tree.child_joint[child] = uj
    if not tree.links:
        raise RobocalError(f"{src}: no <link> elements")
    roots = [n for n in tree.links if n not in tree.child_joint]
    if len(roots) != 1:
        if not roots:
            raise RobocalError(f"{src}: every link is the child of a joint: a closed loop (URDF describes trees)")
        raise RobocalError(f"{src}: {len(roots)} root links ({', '.join(roots)}): the links are not one tree")
    for j in tree.joints.values():
        if j.mimic is not None and j.mimic[0] not in tree.joints:
            raise RobocalError(f"{tree.where('joint', j.name)}: mimics joint {j.mimic[0]!r}, which is not defined")
    return tree


# -- cutting the chain ----------------------------------------------------------------------------------------------
def _path(tree: UrdfTree, base: str, tip: str) -> list[UJoint]:
    """Joints from ``base`` down to ``tip``; error when ``tip`` is not below ``base``."""
    out = []
    link = tip
    while link != base:
        j = tree.child_joint.get(link)
        if j is None:
            raise RobocalError(f"{tree.where('link', tip)}: is not below the base link {base!r}")
        out.append(j)
        link = j.parent
    return out[::-1]


def _subtree_moves(tree: UrdfTree, link: str) -> bool:
    return any(j.type in MOVING or _subtree_moves(tree, j.child) for j in tree.children(link))


def moving_leaves(tree: UrdfTree, base: str) -> list[str]:
    """Children of moving joints below ``base`` below which nothing moves (tip candidates)."""
    out = []

    def walk(link):
        for j in tree.children(link):
            if j.type in MOVING and not _subtree_moves(tree, j.child):
                out.append(j.child)
            walk(j.child)
    walk(base)
    return out


def check_link(tree: UrdfTree, name: str, what: str) -> None:
    if name not in tree.links:
        known = ", ".join(tree.links)
        raise RobocalError(f"{tree.source}: {what} link {name!r} is not in the URDF (links: {known})")


def cut_chain(tree: UrdfTree, base_link: str | None = None, tip_link: str | None = None) -> tuple[str, str, list[UJoint]]:
    base = base_link or tree.root
    check_link(tree, base, "base")
    if tip_link is None:
        leaves = moving_leaves(tree, base)
        if len(leaves) != 1:
            what = "no moving link" if not leaves else f"{len(leaves)} moving leaves ({', '.join(leaves)})"
            raise RobocalError(f"{tree.source}: {what} below {base!r}: choose the chain's end with --tip-link")
        tip_link = leaves[0]
    check_link(tree, tip_link, "tip")
    joints = _path(tree, base, tip_link)
    if not any(j.type in MOVING for j in joints):
        raise RobocalError(f"{tree.source}: no moving joint between {base!r} and {tip_link!r}")
    return base, tip_link, joints


# -- geometry helpers -----------------------------------------------------------------------------------------------
def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    x, y, z = axis
    c, s, C = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


def _hom(R=None, t=None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if t is not None:
        T[:3, 3] = t
    return T


def joint_motion(j: UJoint, q: float) -> np.ndarray:
    """The joint's own motion (4x4) for value q (rad or m), applied after its origin."""
    if j.type == "prismatic":
        return _hom(t=j.axis * q)
    if j.type in ("revolute", "continuous"):
        return _hom(_rot(j.axis, q))
    return np.eye(4)


def dh_matrix(theta, d, a, alpha, beta=0.0) -> np.ndarray:
    """Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta), the link transform of :mod:`calib.kinematics`."""
    ez, ex, ey = np.eye(3)[2], np.eye(3)[0], np.eye(3)[1]
    return (_hom(_rot(ez, theta)) @ _hom(t=[0, 0, d]) @ _hom(t=[a, 0, 0]) @ _hom(_rot(ex, alpha))
            @ _hom(_rot(ey, beta)))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _angle_about(axis, u, v) -> float:
    """Signed angle turning u into v about axis (u, v perpendicular to axis)."""
    return math.atan2(float(np.dot(np.cross(u, v), axis)), float(np.dot(u, v)))


@dataclass
class DHLink:
    theta: float
    d: float
    a: float
    alpha: float
    beta: float
    hayati: bool


def _next_frame(F: np.ndarray, u: np.ndarray, p: np.ndarray) -> DHLink:
    """DH/Hayati parameters taking frame F (z on the current axis) to a frame with z = u through point p."""
    z0, x0, o0 = F[:3, 2], F[:3, 0], F[:3, 3]
    c = float(np.dot(z0, u))
    if abs(c) > math.cos(PARALLEL_DEG * DEG):
        # Hayati: origin where the next axis crosses the plane through o0 normal to z0
        s = float(np.dot(o0 - p, z0)) / c
        o1 = p + s * u
        r = o1 - o0
        a = float(np.linalg.norm(r))
        x1 = r / a if a > 1e-12 else x0
        theta = _angle_about(z0, x0, x1) if a > 1e-12 else 0.0
        y1 = np.cross(z0, x1)
        beta = math.asin(max(-1.0, min(1.0, float(np.dot(u, x1)))))
        alpha = math.atan2(-float(np.dot(u, y1)), float(np.dot(u, z0)))
        return DHLink(theta, 0.0, a, alpha, beta, True)
    # common normal between the line (o0, z0) and the line (p, u)
    w = o0 - p
    b = float(np.dot(z0, u))
    dd, e = float(np.dot(z0, w)), float(np.dot(u, w))
    den = 1 - b * b
    s0 = (b * e - dd) / den                     # along z0 from o0
    s1 = (e - b * dd) / den                     # along u from p
    c0, c1 = o0 + s0 * z0, p + s1 * u
    r = c1 - c0
    a = float(np.linalg.norm(r))
    x1 = r / a if a > 1e-9 else _unit(np.cross(z0, u))
    if a <= 1e-9:
        a = 0.0
    theta = _angle_about(z0, x0, x1)
    alpha = _angle_about(x1, z0, u)
    return DHLink(theta, s0, a, alpha, 0.0, False)


# -- the robot ------------------------------------------------------------------------------------------------------
@dataclass
class UrdfChain:
    """The cut robot in numbers -- one chain, or the tree from the base to every link that carries a point: what
    :func:`calib.urdf.robot_from_urdf` turns into a Robot.

    One entry per *internal link* of the Robot: a moving joint's own link (its DH/Hayati parameters to its first
    moving child's axis), a *branch* link for each further child (the same joint variable, its own common normal to
    that child's axis: ``variable_of``), and a *fixed* link for each further root of the tree (a branch leaving the
    base link before any joint moves)."""

    tree: UrdfTree
    base_link: str
    tip_link: str                       # the last point link (a chain: the tip)
    axes: list[UJoint]                  # per internal link: its joint (a branch link: the joint it shares)
    links: list[DHLink]
    frame0_in_base: np.ndarray          # (4, 4), mm
    tip_in_frame_n: np.ndarray          # (4, 4), mm: the tip link's frame in its DH frame
    mass_kg: np.ndarray
    com_mm: np.ndarray                  # (n, 3) in DH frame j
    limits: np.ndarray                  # (n, 2) rad or mm
    prismatic: np.ndarray
    readings: list[str]                 # the joints whose values the data give (mimic leaders off the tree too)
    reading_matrix: np.ndarray          # (n, m): axis value = M @ reading + offset
    reading_offset: np.ndarray          # (n,) rad or mm
    parent_frame: np.ndarray | None = None      # (n,) the frame each internal link starts from
    variable_of: np.ndarray | None = None       # (n,) the link whose variable it shares (-1: fixed)
    link_names: list[str] | None = None         # (n,) the joint's name; "J->C" for a branch link
    point_frames: dict[str, tuple[int, np.ndarray]] | None = None  # point link -> (frame, its pose in that frame)
    children: list[str | None] | None = None    # (n,) the joint whose axis each link's end frame is on (None: a leaf)


def _to_mm(T: np.ndarray) -> np.ndarray:
    T = T.copy()
    T[:3, 3] *= 1000.0
    return T


def _frame0(base_T_axis: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Frame 0: z on the first axis, origin its point nearest the base origin, x nearest the base x."""
    p = base_T_axis[:3, 3]
    o = p - np.dot(p, u) * u
    ex = np.array([1.0, 0, 0])
    x = ex - np.dot(ex, u) * u
    if np.linalg.norm(x) < 1e-6:
        ey = np.array([0.0, 1, 0])
        x = ey - np.dot(ey, u) * u
    x = _unit(x)
    return _hom(np.column_stack([x, np.cross(u, x), u]), o)


def analyse_chain(tree: UrdfTree, base_link: str | None = None, tip_link: str | None = None) -> UrdfChain:
    """One chain of the tree, from ``base_link`` to ``tip_link`` (see :func:`cut_chain` for the defaults)."""
    base, tip, _ = cut_chain(tree, base_link, tip_link)
    return analyse_tree(tree, base, [tip])


def analyse_tree(tree: UrdfTree, base_link: str | None, point_links: list[str]) -> UrdfChain:
    """The robot from ``base_link`` to every link of ``point_links``: one chain for one link, else the tree of
    their paths, the joints several paths share taken once (a torso under two arms is one set of parameters)."""
    base = base_link or tree.root
    check_link(tree, base, "base")
    for link in point_links:
        check_link(tree, link, "point")
    paths = [_path(tree, base, link) for link in point_links]
    in_tree = {j.name for path in paths for j in path}
    if not any(j.type in MOVING for path in paths for j in path):
        raise RobocalError(f"{tree.source}: no moving joint between {base!r} and {', '.join(map(repr, point_links))}")
    T_link = {base: np.eye(4)}                         # every link's frame at q = 0 in the base link, mm

    def place(link):
        for c in tree.children(link):
            T_link[c.child] = T_link[link] @ _to_mm(c.origin)
            place(c.child)
    place(base)
    # the moving joints of the tree, parents first (depth first, in the URDF's order), with their moving parent
    moving: list[UJoint] = []
    moving_parent: dict[str, str | None] = {}

    def walk(link, above):
        for c in tree.children(link):
            if c.name not in in_tree:
                continue
            if c.type in MOVING:
                moving.append(c)
                moving_parent[c.name] = above
                walk(c.child, c.name)
            else:
                walk(c.child, above)
    walk(base, None)
    kids = {None: [j for j in moving if moving_parent[j.name] is None]}
    for j in moving:
        kids[j.name] = [c for c in moving if moving_parent[c.name] == j.name]
    axis_T = {j.name: T_link[j.parent] @ _to_mm(j.origin) for j in moving}
    u = {k: _unit(T[:3, :3] @ tree.joints[k].axis) for k, T in axis_T.items()}
    p = {k: T[:3, 3] for k, T in axis_T.items()}
    roots = kids[None]
    F0 = _frame0(axis_T[roots[0].name], u[roots[0].name])
    # internal links: (joint, shared-variable link or None, fixed?, parent frame, the child axis its end frame is on)
    links: list[DHLink] = []
    axes: list[UJoint] = []
    parent_frame: list[int] = []
    variable_of: list[int] = []
    link_names: list[str] = []
    children: list[str | None] = []
    frames = [F0]
    start_frame: dict[str, int] = {roots[0].name: 0}
    own_link: dict[str, int] = {}

    def add(joint: UJoint, pf: int, var: int, name: str, child: str | None, fixed: bool = False) -> int:
        F = frames[pf]
        L = _next_frame(F, u[child], p[child]) if child is not None else DHLink(0.0, 0.0, 0.0, 0.0, 0.0, False)
        i = len(links)
        links.append(L), axes.append(joint), parent_frame.append(pf), link_names.append(name)
        variable_of.append(i if var == -2 else var), children.append(child)
        frames.append(F @ dh_matrix(L.theta, L.d, L.a, L.alpha, L.beta))
        if child is not None:
            start_frame[child] = i + 1
        return i

    for r in roots[1:]:                                 # further roots: a fixed link from frame 0 to each axis
        fixed = UJoint(f"{base}-{r.name}", "fixed", base, r.parent, np.eye(4), np.array([0.0, 0, 1]), None, None)
        add(fixed, 0, -1, fixed.name, r.name, fixed=True)
    for j in moving:                                    # parents first: each joint's axis frame exists already
        pf = start_frame[j.name]
        ch = kids[j.name]
        own_link[j.name] = add(j, pf, -2, j.name, ch[0].name if ch else None)
        for c in ch[1:]:
            add(j, pf, own_link[j.name], f"{j.name}-{c.name}", c.name)
    n = len(links)
    # mass and centre of mass of what each joint's own link carries rigidly (side branches held at zero included)
    mass, com = np.zeros(n), np.zeros((n, 3))
    for j in moving:
        k = own_link[j.name]
        total, moment = 0.0, np.zeros(3)
        stack = [j.child]
        while stack:
            link = stack.pop()
            ln = tree.links[link]
            T = T_link[link]
            total += ln.mass_kg
            moment += ln.mass_kg * (T[:3, :3] @ (ln.com_m * 1000.0) + T[:3, 3])
            stack += [c.child for c in tree.children(link) if not (c.type in MOVING and c.name in in_tree)]
        mass[k] = total
        if total > 0:
            Fi = np.linalg.inv(frames[k + 1])
            com[k] = Fi[:3, :3] @ (moment / total) + Fi[:3, 3]
    limits = np.zeros((n, 2))
    for k, j in enumerate(axes):
        if j.type == "fixed":
            limits[k] = (0.0, 0.0)
        elif j.type == "continuous" or j.limits is None:
            limits[k] = (-CONTINUOUS_LIMIT_RAD, CONTINUOUS_LIMIT_RAD) if j.type != "prismatic" else (-1e6, 1e6)
        else:
            limits[k] = np.array(j.limits) * (1000.0 if j.type == "prismatic" else 1.0)
    # readings: the tree's non-mimic joints, then any joint a mimic joint follows from off the tree (a lifting
    # column's telescoping stages following a leader on a side branch): its value comes from its data column
    readings = [j.name for j in moving if j.mimic is None]
    for j in moving:
        if j.mimic is not None:
            leader = _resolve_mimic(tree, j)[0]
            if leader not in readings:
                readings.append(leader)
    M = np.zeros((n, len(readings)))
    off = np.zeros(n)
    for k, j in enumerate(axes):
        if j.type == "fixed":
            continue
        if j.mimic is None:
            M[k, readings.index(j.name)] = 1.0
        else:
            name, mult, offset = _resolve_mimic(tree, j)
            scale = 1000.0 if j.type == "prismatic" else 1.0          # mm per SI unit of the mimic joint
            fscale = 1000.0 if tree.joints[name].type == "prismatic" else 1.0
            M[k, readings.index(name)] = mult * scale / fscale
            off[k] = offset * scale
    # every point link on the frame of the nearest moving joint above it (frame 0 when none moves above it)
    point_frames = {}
    for link, path in zip(point_links, paths):
        above = [j for j in path if j.type in MOVING]
        f = own_link[above[-1].name] + 1 if above else 0
        point_frames[link] = (f, np.linalg.inv(frames[f]) @ T_link[link])
    tip = point_links[-1]
    return UrdfChain(tree, base, tip, axes, links, frames[0], point_frames[tip][1], mass, com, limits,
                     np.array([j.type == "prismatic" for j in axes]), readings, M, off,
                     np.array(parent_frame, int), np.array(variable_of, int), link_names, point_frames, children)


def _resolve_mimic(tree: UrdfTree, j: UJoint) -> tuple[str, float, float]:
    """Follow a mimic chain to a non-mimic joint: (name, multiplier, offset)."""
    name, mult, off = j.mimic
    seen = {j.name}
    while tree.joints[name].mimic is not None:
        if name in seen:
            raise RobocalError(f"{tree.where('joint', j.name)}: mimic joints follow each other in a loop")
        seen.add(name)
        n2, m2, o2 = tree.joints[name].mimic
        name, mult, off = n2, mult * m2, mult * o2 + off
    return name, mult, off


def urdf_link_pose_mm(chain: UrdfChain, readings: np.ndarray, link: str | None = None) -> np.ndarray:
    """A link's frame (4x4, mm, base link) straight from the URDF joints for the chain's readings (default the tip
    link): the reference robocal's kinematics are tested against."""
    tree = chain.tree
    vals = chain.reading_matrix @ np.asarray(readings, float) + chain.reading_offset
    by_name = {j.name: v for j, v in zip(chain.axes, vals) if j.type != "fixed"}
    T = np.eye(4)
    for j in _path(tree, chain.base_link, link or chain.tip_link):
        v = by_name.get(j.name, 0.0)
        T = T @ _to_mm(j.origin) @ _to_mm(joint_motion(j, v / 1000.0 if j.type == "prismatic" else v))
    return T


def urdf_forward_mm(chain: UrdfChain, readings: np.ndarray, link: str | None = None) -> np.ndarray:
    """The tip link origin (mm, base link) straight from the URDF joints (reference for tests and fk)."""
    return urdf_link_pose_mm(chain, readings, link)[:3, 3]


def parameter_meaning(chain: UrdfChain) -> dict[str, str]:
    """Which URDF quantity each kinematic parameter of the robot corrects (for reports and ``--free``)."""
    out = {}
    ax = chain.axes
    children = chain.children or [ax[k + 1].name if k + 1 < len(ax) else None for k in range(len(ax))]
    for k, (j, nx) in enumerate(zip(ax, children)):
        p = f"j{k + 1}"
        if j.type == "fixed":
            for q in ("theta_offset_rad", "d_mm", "a_mm", "alpha_rad", "beta_rad"):
                out[f"{p}.{q}"] = f"pose of {nx}'s axis on {chain.base_link} (origins of the joints above {nx})"
        elif nx is not None:
            out[f"{p}.theta_offset_rad"] = (f"zero of {j.name} (a rotation of {nx}'s origin about {j.name}'s axis)"
                                            if j.type != "prismatic" else f"direction of {j.name}'s common normal")
            out[f"{p}.d_mm"] = (f"{'travel of ' + j.name + ' / ' if j.type == 'prismatic' else ''}"
                                f"position of {nx}'s origin along {j.name}'s axis (origin xyz of {nx})")
            out[f"{p}.a_mm"] = f"distance between the axes of {j.name} and {nx} (origin xyz of {nx})"
            out[f"{p}.alpha_rad"] = f"angle between the axes of {j.name} and {nx} (origin rpy / axis of {nx})"
            out[f"{p}.beta_rad"] = (f"tilt of {nx}'s axis towards the common normal (origin rpy / axis of {nx}; "
                                    "Hayati, the axes are nearly parallel)")
        else:
            on = [lk for lk, (f, _) in (chain.point_frames or {}).items() if f == k + 1] or [chain.tip_link]
            for q in ("theta_offset_rad", "d_mm", "a_mm", "alpha_rad", "beta_rad"):
                out[f"{p}.{q}"] = f"zero of {j.name} / pose of {', '.join(on)} on it"
    for q in ("x_mm", "y_mm", "z_mm", "yaw_rad", "pitch_rad", "roll_rad"):
        out[f"base.{q}"] = f"pose of {ax[0].name}'s axis in the measurement frame (origin of {ax[0].name} and above)"
    for q in ("x_mm", "y_mm", "z_mm"):
        out[f"tool.{q}"] = f"tool point on {chain.tip_link} (origins of the fixed joints after {ax[-1].name})"
    return out


def robot_from_urdf(path: str | Path, base_link: str | None = None, tip_link: str | None = None,
                    tool_points_mm: dict[str, np.ndarray] | None = None) -> Robot:
    """Import one chain of a URDF (see :mod:`calib.urdf`); tool points are given in the tip link's frame (mm)."""
    ch = analyse_chain(read_urdf(path), base_link, tip_link)
    pts = tool_points_mm if tool_points_mm else {ch.tip_link: np.zeros(3)}
    return robot_from_analysis(ch, {k: (ch.tip_link, v) for k, v in pts.items()}, source=str(path))


def robot_from_analysis(ch, points: dict[str, tuple[str, np.ndarray]], source: str, name: str = "",
                        base_in_world: np.ndarray | None = None, **fields) -> Robot:
    """The Robot of an analysed URDF chain or tree (:class:`calib.urdf.UrdfChain`): ``points`` name -> (link, xyz
    in that link's frame, mm); ``base_in_world`` the base link in the measurement frame (default identity);
    ``fields`` any other Robot field (drives, readings)."""
    n = len(ch.links)
    tool, frames = {}, {}
    for key, (link, xyz) in points.items():
        f, T = ch.point_frames[link]
        tool[key] = T[:3, :3] @ np.asarray(xyz, float) + T[:3, 3]
        frames[key] = int(f)
    F0 = ch.frame0_in_base
    B = np.eye(4) if base_in_world is None else base_in_world
    W0 = B @ F0                                                       # frame 0 in the measurement frame

    def col(attr):
        return np.array([getattr(L, attr) for L in ch.links], float)

    ends = sorted({link for link, _ in points.values()})
    cut = ch.tip_link if len(ends) == 1 else "{" + ", ".join(ends) + "}"
    kw = dict(
        name=name or f"{ch.tree.name} ({ch.base_link} -> {cut})",
        a_mm=col("a"), d_mm=col("d"), alpha_rad=col("alpha"), theta_offset_rad=col("theta"), beta_rad=col("beta"),
        hayati=np.array([L.hayati for L in ch.links], bool), limits_rad=ch.limits,
        gear_ratio=np.ones(n), counts_per_rev=np.full(n, 2.0 ** 20), mass_kg=ch.mass_kg, com_mm=ch.com_mm,
        coupling=np.eye(n), gravity_m_s2=W0[:3, :3].T @ (B[:3, :3] @ np.array([0.0, 0.0, -G0_M_S2])),
        base_xyz_mm=W0[:3, 3].copy(), base_rpy_rad=rpy_from_matrix(W0[:3, :3]),
        tool_points_mm=tool, tool_point_frames=frames, joint_names=tuple(ch.link_names), source=source,
        prismatic=ch.prismatic, frame0_in_base=F0, reading_names=tuple(ch.readings),
        reading_matrix=ch.reading_matrix, reading_offset=ch.reading_offset, param_meaning=parameter_meaning(ch),
        parent_frame=ch.parent_frame, variable_of=ch.variable_of,
    )
    kw.update(fields)
    robot = Robot(**kw)
    return replace(robot, urdf_pivot_mm=_pivots_mm(ch, robot, B))


def _pivots_mm(ch: UrdfChain, robot: Robot, base_in_world: np.ndarray) -> np.ndarray:
    """Per internal link, the URDF joint's origin as a signed distance (mm) along the joint's axis from the origin
    of robocal's frame of that joint, both at zero joint values (the pivot a lateral compliance bends about; 0 for a
    fixed link)."""
    fp = Kinematics(robot).forward(np.zeros((1, robot.n)))
    out = np.zeros(robot.n)
    var = robot.variable_of if robot.variable_of is not None else np.arange(robot.n)
    for k, j in enumerate(ch.axes):
        if var[k] < 0 or j.type == "fixed":
            continue
        T = np.eye(4)
        for step in _path(ch.tree, ch.base_link, j.child):
            T = T @ _to_mm(step.origin)
        p = (base_in_world @ T)[:3, 3]
        out[k] = float((p - fp.joint_origin[0, k]) @ fp.joint_axis[0, k])
    return out
