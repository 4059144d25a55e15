"""Robot description: the kinematic, drive and mass data of a serial robot, read from a documented TOML file.

The format (``calib/data/puma560.toml`` is the annotated example and the default robot):

``[robot]``
    ``name`` (str), ``gravity_m_s2`` (3 numbers, gravity in base frame 0; default ``[0, 0, -9.80665]``).
``[[joint]]`` (one table per joint, base to wrist)
    ``type`` (``revolute``, default, or ``prismatic``: the joint variable, in mm, then adds to d; limits in mm).
    Standard Denavit-Hartenberg link ``A_j = Rot(z, theta_j + theta_offset) Trans(z, d) Trans(x, a) Rot(x, alpha)
    Rot(y, beta)``: ``a_mm``, ``d_mm``, ``alpha_deg`` (required), ``theta_offset_deg`` (default 0), ``beta_deg`` (the
    Hayati rotation, default 0) and ``hayati`` (true when this link joins two nominally parallel axes: beta is then
    identified instead of d).  A joint reading is ``theta_j``.  Drive: ``limits_deg`` ([low, high]), ``gear_ratio``
    (motor angle = gear_ratio x joint angle, sign included), ``encoder_counts_per_rev`` (counts per motor revolution,
    after quadrature).  Gravity: ``mass_kg`` and ``com_mm`` (centre of mass in frame j).
``[coupling]``
    The motor-from-joint map ``motor = diag(G) (C theta)``.  Either ``sigma45``, ``sigma46``, ``sigma56`` (wrist
    coupling factors, C lower triangular) or a full ``matrix`` (n x n).  Default: no coupling.
``[base]``
    Pose of robot frame 0 in the measurement (theodolite) frame: ``xyz_mm``, ``rpy_deg`` (roll-pitch-yaw, applied as
    Rz(yaw) Ry(pitch) Rx(roll)).  Default: identity.
``[tool.points]``
    Named tool points in frame 6, mm (``P = [0, 0, 150]``).  None means the origin of frame 6.  The thesis's ^6E
    (rotation diag(-1,-1,-1), translation -(Xt, Yt, Zt)) puts its tool point at ``[-Xt, -Yt, -Zt]``.  On a branched
    robot a point names the joint whose link carries it: ``L = { link = "arm_left_7_joint", xyz_mm = [0, 0, 50] }``.

Branched robots (trees; written by robocal for an identified tree): a joint's ``parent`` names the joint whose link
end its axis sits on (``"base"``: frame 0; default the previous joint); ``shares = "J"`` makes the link a branch of
joint J (it turns with J's variable: the common normal from J's axis to a second child's axis); ``fixed = true`` a
fixed link (a branch leaving the base before any joint).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field, replace

import numpy as np

from .angles import rpy_from_matrix, rpy_matrix
from .errors import RobocalError
from .names import joint_label
from .tomlspec import Checker, Field, check_each
from .units import DEG, G0_M_S2

JOINT_SPEC = {
    "name": Field("str", default=""),
    "type": Field("str", default="revolute"),
    "a_mm": Field("number", required=True),
    "d_mm": Field("number", required=True),
    "alpha_deg": Field("number", required=True, min=-360, max=360),
    "theta_offset_deg": Field("number", default=0.0, min=-360, max=360),
    "beta_deg": Field("number", default=0.0, min=-90, max=90),
    "hayati": Field("bool", default=False),
    "limits_deg": Field("vector", length=2, min=-720, max=720),
    "limits_mm": Field("vector", length=2),
    "gear_ratio": Field("number", required=True),
    "encoder_counts_per_rev": Field("int", required=True, positive=True),
    "mass_kg": Field("number", default=0.0, min=0.0),
    "com_mm": Field("vector", default=[0.0, 0.0, 0.0], length=3),
    # a branched robot: the joint whose link end this joint's axis sits on ("base": frame 0; default the previous
    # joint), and for a branch link the joint whose variable it turns with, or fixed = true for a fixed link
    "parent": Field("str", default=""),
    "shares": Field("str", default=""),
    "fixed": Field("bool", default=False),
}
ROBOT_SPEC = {
    "name": Field("str", default="robot"),
    "gravity_m_s2": Field("vector", default=[0.0, 0.0, -G0_M_S2], length=3),
}
TOP_SPEC = {
    "robot": Field("table", default={}),
    "joint": Field("tables", required=True),
    "coupling": Field("table", default={}),
    "base": Field("table", default={}),
    "tool": Field("table", default={}),
    "readings": Field("table", default={}),
}
COUPLING_SPEC = {
    "sigma45": Field("number", default=0.0, min=-1, max=1),
    "sigma46": Field("number", default=0.0, min=-1, max=1),
    "sigma56": Field("number", default=0.0, min=-1, max=1),
    "matrix": Field("matrix"),
}
BASE_SPEC = {
    "xyz_mm": Field("vector", default=[0.0, 0.0, 0.0], length=3),
    "rpy_deg": Field("vector", default=[0.0, 0.0, 0.0], length=3, min=-360, max=360),
    # frame 0 in the description's own base frame (a URDF's base link): what ``robocal fk`` reports in
    "frame0_xyz_mm": Field("vector", default=[0.0, 0.0, 0.0], length=3),
    "frame0_rpy_deg": Field("vector", default=[0.0, 0.0, 0.0], length=3, min=-360, max=360),
}
TOOL_SPEC = {"points": Field("table", default={})}


@dataclass(frozen=True)
class Robot:
    """A serial robot with n revolute joints.  Arrays are indexed by joint (0-based inside, 1-based in names)."""

    name: str
    a_mm: np.ndarray
    d_mm: np.ndarray
    alpha_rad: np.ndarray
    theta_offset_rad: np.ndarray
    beta_rad: np.ndarray
    hayati: np.ndarray                 # bool per link: beta identified instead of d
    limits_rad: np.ndarray             # (n, 2): rad, or mm for a prismatic joint
    gear_ratio: np.ndarray
    counts_per_rev: np.ndarray
    mass_kg: np.ndarray
    com_mm: np.ndarray                 # (n, 3), in frame j
    coupling: np.ndarray               # (n, n) C in motor = diag(G) C theta
    gravity_m_s2: np.ndarray           # (3,) in frame 0
    base_xyz_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    base_rpy_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tool_points_mm: dict[str, np.ndarray] = field(default_factory=dict)
    joint_names: tuple[str, ...] = ()
    source: str = "<memory>"
    prismatic: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # joint variable adds to d (mm)
    # frame 0 in the description's own base frame (a URDF's base link); identity for a DH description
    frame0_in_base: np.ndarray = field(default_factory=lambda: np.eye(4))
    # controller readings -> joint variables: theta = reading_matrix @ r + reading_offset (internal units); the
    # readings are what a pose CSV and ``robocal fk`` give (mimic joints and reading conventions are not readings)
    reading_names: tuple[str, ...] = ()
    reading_matrix: np.ndarray | None = None
    reading_offset: np.ndarray | None = None
    reading_prismatic: np.ndarray | None = None
    # which description quantity each kinematic parameter corrects (URDF imports), and priors (1-sigma) by name
    param_meaning: dict[str, str] = field(default_factory=dict)
    tolerances: dict[str, float] = field(default_factory=dict)
    # a branched robot (a tree): link j starts at frame parent_frame[j] (0 the base frame, k + 1 the end of link k;
    # a chain has parent_frame[j] = j).  A link that shares another's joint variable (the second branch leaving a
    # joint: its common normal to the other child's axis) has that link's index in variable_of; a fixed link
    # (a branch leaving a body before any joint) has -1; every other link has its own index.
    parent_frame: np.ndarray | None = None
    variable_of: np.ndarray | None = None
    # the frame each tool point is fixed in (0..n); a point not named here is on frame n (the chain's tip)
    tool_point_frames: dict[str, int] = field(default_factory=dict)
    # per link, where its joint's bearing is: the URDF joint's origin, as the signed distance (mm) along the joint's
    # axis from the origin of robocal's frame of that joint (a DH/Hayati frame lies where the common normals put it,
    # up to a link's length away); None (every pivot at the frame's origin) for a description not built from a URDF
    urdf_pivot_mm: np.ndarray | None = None

    def __post_init__(self):
        if self.prismatic.size != len(self.a_mm):
            object.__setattr__(self, "prismatic", np.zeros(len(self.a_mm), bool))
        if not self.joint_names:
            object.__setattr__(self, "joint_names", tuple(f"j{i}" for i in range(1, self.n + 1)))
        if self.parent_frame is None:
            object.__setattr__(self, "parent_frame", np.arange(self.n))
        if self.variable_of is None:
            object.__setattr__(self, "variable_of", np.arange(self.n))
        pf = np.asarray(self.parent_frame, int)
        if pf.shape != (self.n,) or np.any(pf < 0) or np.any(pf > np.arange(self.n)):
            raise ValueError(f"parent_frame must give each link j a frame 0..j, got {self.parent_frame!r}")
        object.__setattr__(self, "parent_frame", pf)
        object.__setattr__(self, "variable_of", np.asarray(self.variable_of, int))
        if self.reading_matrix is None:
            object.__setattr__(self, "reading_matrix", np.eye(self.n))
            object.__setattr__(self, "reading_names", tuple(self.joint_names))
            object.__setattr__(self, "reading_prismatic", self.prismatic.copy())
        if self.reading_offset is None:
            object.__setattr__(self, "reading_offset", np.zeros(self.n))
        if self.reading_prismatic is None:
            pris = np.array([bool(np.any(self.prismatic[self.reading_matrix[:, k] != 0]))
                             for k in range(self.reading_matrix.shape[1])], bool)
            object.__setattr__(self, "reading_prismatic", pris)

    @property
    def description_joint_names(self) -> tuple[str, ...] | None:
        """The joint names reports use instead of the thesis's Puma names: those of an imported description (URDF);
        None for a DH description, which keeps the thesis's vocabulary."""
        return self.joint_names if self.param_meaning else None

    # -- readings -----------------------------------------------------------------------------------------------
    @property
    def n_readings(self) -> int:
        return self.reading_matrix.shape[1]

    @property
    def readings_are_joints(self) -> bool:
        """True when every reading is one joint variable (no mimic joint, no reading convention)."""
        return (self.reading_matrix.shape == (self.n, self.n) and np.array_equal(self.reading_matrix, np.eye(self.n))
                and not np.any(self.reading_offset))

    def joints_from_readings(self, r) -> np.ndarray:
        """Joint variables (..., n) in rad / mm from controller readings (..., m) in rad / mm."""
        return np.asarray(r, float) @ self.reading_matrix.T + self.reading_offset

    def readings_from_joints(self, q) -> np.ndarray:
        """Controller readings (..., m) that give joint variables (..., n): the inverse of
        :meth:`joints_from_readings` (least squares; exact for joint variables that readings can give)."""
        q = np.asarray(q, float)
        sol = np.linalg.lstsq(self.reading_matrix, (q - self.reading_offset).reshape(-1, self.n).T, rcond=None)[0]
        return sol.T.reshape(q.shape[:-1] + (self.n_readings,))

    def reading_limits(self) -> np.ndarray:
        """(m, 2) the range of each reading: the limits of every joint that follows it alone (a mimic joint's range
        divided by its multiplier), intersected; a reading that only enters combinations keeps +-180 deg (+-1 m)."""
        M, off = self.reading_matrix, self.reading_offset
        out = np.where(self.reading_prismatic[:, None], [[-1000.0, 1000.0]], [[-np.pi, np.pi]])
        seen = np.zeros(self.n_readings, bool)
        for k in range(self.n):
            cols = np.flatnonzero(M[k])
            if len(cols) != 1 or self.variable_of[k] < 0:
                continue
            c = cols[0]
            lo, hi = sorted((self.limits_rad[k] - off[k]) / M[k, c])
            out[c] = (max(out[c, 0], lo), min(out[c, 1], hi)) if seen[c] else (lo, hi)
            seen[c] = True
        return out

    @property
    def reading_edge_scale(self) -> np.ndarray:
        """Internal units per edge unit of each reading: rad per degree, or 1 (mm) for a prismatic one."""
        return np.where(self.reading_prismatic, 1.0, DEG)

    @property
    def edge_scale(self) -> np.ndarray:
        """Internal units per edge unit of each joint variable: rad per degree (revolute), mm per mm (prismatic)."""
        return np.where(self.prismatic, 1.0, DEG)

    @property
    def n(self) -> int:
        return len(self.a_mm)

    @property
    def is_tree(self) -> bool:
        """True for a branched robot (some link does not start where the previous one ends)."""
        return bool(np.any(self.parent_frame != np.arange(self.n)))

    def point_frame(self, name: str | None = None) -> int:
        """The frame (0..n) a tool point is fixed in: its own link's for a branched robot, else frame n."""
        if name is None:
            name = self.reference_point_name()
        return int(self.tool_point_frames.get(name, self.n)) if name is not None else self.n

    def reference_point_name(self) -> str | None:
        """The tool point :meth:`tool_point` returns without a name (None: no point is described)."""
        if not self.tool_points_mm:
            return None
        if len(self.tool_points_mm) == 1:
            return next(iter(self.tool_points_mm))
        return "P" if "P" in self.tool_points_mm else next(iter(self.tool_points_mm))

    def frame_ancestors(self) -> np.ndarray:
        """(n+1, n+1) bool: ``A[b, f]`` when frame f is frame b or lies between it and the base (a point fixed in
        frame b moves with every link whose end frame f is such an ancestor)."""
        n = self.n
        A = np.eye(n + 1, dtype=bool)
        for j in range(n):                      # links are in topological order: a parent frame comes first
            A[j + 1] |= A[self.parent_frame[j]]
        return A

    def frames_moved(self) -> np.ndarray:
        """(n, n+1) bool: ``M[j, f]`` when frame f moves with link j's joint variable -- below link j's end, or
        below the end of a link sharing its variable (the other branches leaving the same joint)."""
        A = self.frame_ancestors()
        own = A[:, 1:].T                                                       # (n, n+1): f below link j's end
        var = self.variable_of
        M = own.copy()
        for j in range(self.n):
            if var[j] >= 0:
                M[j] = np.any(own[var == var[j]], axis=0)
        return M

    def variable_spread(self) -> np.ndarray:
        """(n, n): a change of each link's joint variable carried to every link that shares it
        (``dq_links = dq @ S.T``); identity for a chain, zero rows for fixed links."""
        n = self.n
        S = np.zeros((n, n))
        for j, v in enumerate(self.variable_of):
            if v >= 0:
                S[j, v] = 1.0
        return S

    # -- tool -------------------------------------------------------------------------------------------------
    def tool_point(self, name: str | None = None) -> np.ndarray:
        """A named tool point in its frame (mm; frame n of a chain); with no name the reference point
        (:meth:`reference_point_name`), or the origin of frame n if none is described."""
        if name is None:
            name = self.reference_point_name()
            if name is None:
                return np.zeros(3)
        try:
            return self.tool_points_mm[name].copy()
        except KeyError:
            known = ", ".join(self.tool_points_mm) or "none"
            raise RobocalError(f"{self.source}: tool point {name!r} is not defined (defined: {known})") from None

    def with_tool(self, points_mm: dict[str, np.ndarray]) -> "Robot":
        """The robot with these tool points (names keep the frames they are described on; new names: frame n)."""
        return replace(self, tool_points_mm={k: np.asarray(v, float) for k, v in points_mm.items()},
                       tool_point_frames={k: f for k, f in self.tool_point_frames.items() if k in points_mm})

    # -- encoders ---------------------------------------------------------------------------------------------
    def motor_angles_rad(self, theta_rad: np.ndarray) -> np.ndarray:
        """Motor shaft angles for joint angles (..., n): ``diag(G) C theta``."""
        return (np.asarray(theta_rad) @ self.coupling.T) * self.gear_ratio

    def joint_angles_from_motor(self, motor_rad: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`motor_angles_rad`."""
        return np.linalg.solve(self.coupling, (np.asarray(motor_rad) / self.gear_ratio).T).T

    def counts_from_joint(self, theta_rad: np.ndarray) -> np.ndarray:
        """Encoder counts (float, unrounded) that joint angles produce; zero counts at zero joint angles."""
        return self.motor_angles_rad(theta_rad) * self.counts_per_rev / (2 * np.pi)

    def joint_from_counts(self, counts: np.ndarray) -> np.ndarray:
        """Joint angles (rad) from encoder counts, undoing gear ratios and the coupling matrix."""
        return self.joint_angles_from_motor(np.asarray(counts, float) * (2 * np.pi) / self.counts_per_rev)

    def within_limits(self, theta_rad: np.ndarray) -> np.ndarray:
        """Boolean per pose: every joint inside its limits."""
        q = np.atleast_2d(theta_rad)
        return np.all((q >= self.limits_rad[:, 0]) & (q <= self.limits_rad[:, 1]), axis=-1)

    def check_readings(self, q_edge: np.ndarray, where: str) -> None:
        """Refuse joint readings (degrees, mm for a prismatic joint) that no robot of this description can give.

        A revolute reading beyond two turns, or a prismatic one further outside its limits than the stroke, is a
        typing or unit mistake (``fk 1e308 ...``, radians for degrees) rather than a pose: one line naming the joint.
        """
        q = np.atleast_2d(np.asarray(q_edge, float))
        lim = self.limits_rad / self.edge_scale[:, None]
        span = lim[:, 1] - lim[:, 0]
        lo = np.where(self.prismatic, lim[:, 0] - span, -720.0)
        hi = np.where(self.prismatic, lim[:, 1] + span, 720.0)
        bad = ~np.isfinite(q) | (q < lo) | (q > hi)
        if bad.any():
            row, j = map(int, np.argwhere(bad)[0])
            unit = "mm" if self.prismatic[j] else "deg"
            pose = f"pose {row + 1}: " if q.shape[0] > 1 else ""
            raise RobocalError(f"{where}: {pose}{joint_label(self, j + 1)} reading {q[row, j]:g} {unit} is outside "
                               f"{lo[j]:g}..{hi[j]:g} {unit} (a typing or unit mistake?)")


def _coupling_matrix(chk: Checker, c: dict, n: int) -> np.ndarray:
    if c["matrix"] is not None:
        if any(c[k] != 0.0 for k in ("sigma45", "sigma46", "sigma56")):
            chk.fail("coupling", "give either the sigma factors or the matrix, not both")
        m = np.asarray(c["matrix"], float)
        if m.shape != (n, n):
            chk.fail("coupling.matrix", f"must be {n}x{n} for {n} joints, got {m.shape[0]}x{m.shape[1] if m.ndim > 1 else 0}")
        if abs(np.linalg.det(m)) < 1e-9:
            chk.fail("coupling.matrix", "is singular: joint angles could not be recovered from motor angles")
        return m
    m = np.eye(n)
    sig = {"sigma45": (4, 3), "sigma46": (5, 3), "sigma56": (5, 4)}
    for key, (i, j) in sig.items():
        if c[key] != 0.0:
            if n < 6:
                chk.fail(f"coupling.{key}", f"needs 6 joints, the robot has {n}")
            m[i, j] = c[key]
    return m


def parse_robot(text: str, source: str = "<string>") -> Robot:
    """Parse and check a robot description given as TOML text."""
    chk, data = Checker.parse(text, source)
    return robot_from_table(chk, data)


def robot_from_table(chk: Checker, data: dict) -> Robot:
    """The Robot of a checked DH description table (the TOML of this module, already parsed)."""
    top = chk.table(data, TOP_SPEC, "")
    rob = chk.table(top["robot"], ROBOT_SPEC, "robot")
    joints = check_each(chk, top["joint"], JOINT_SPEC, "joint", lambda j, key: (j, key))
    if not joints:
        chk.fail("joint", "at least one [[joint]] table is needed")
    for j, key in joints:
        lkey = "limits_mm" if j["type"] == "prismatic" else "limits_deg"
        other = "limits_deg" if lkey == "limits_mm" else "limits_mm"
        if j[lkey] is None:
            chk.fail(f"{key}.{lkey}", "missing")
        if j[other] is not None:
            chk.fail(f"{key}.{other}", f"does not apply to a {j['type']} joint (use {lkey})")
        lo, hi = j[lkey]
        if not lo < hi:
            chk.fail(f"{key}.{lkey}", f"low limit {lo:g} must be below high limit {hi:g}")
        if j["type"] not in ("revolute", "prismatic"):
            chk.fail(f"{key}.type", f"must be revolute or prismatic, got {j['type']!r}")
        if j["gear_ratio"] == 0.0:
            chk.fail(f"{key}.gear_ratio", "must not be zero")
    js = [j for j, _ in joints]
    n = len(js)
    coupling = _coupling_matrix(chk, chk.table(top["coupling"], COUPLING_SPEC, "coupling"), n)
    base = chk.table(top["base"], BASE_SPEC, "base")
    tool = chk.table(top["tool"], TOOL_SPEC, "tool")
    names = [j["name"] or f"j{i}" for i, j in enumerate(js, 1)]
    if len(set(names)) != len(names):
        chk.fail("joint", "two joints have the same name")
    parent, variable = _tree_fields(chk, joints, names)
    points, frames = {}, {}
    if not isinstance(tool["points"], dict):
        chk.fail("tool.points", "must be a table of name = [x, y, z]")
    for name, vec in tool["points"].items():
        key = f"tool.points.{name}"
        if isinstance(vec, dict):
            if set(vec) - {"link", "xyz_mm"} or vec.get("link") not in ["base"] + names:
                chk.fail(key, f'must be {{ link = "JOINT", xyz_mm = [x, y, z] }} with a joint of {", ".join(names)}')
            frames[name] = 0 if vec["link"] == "base" else names.index(vec["link"]) + 1
            vec = vec.get("xyz_mm", [0.0, 0.0, 0.0])
            key += ".xyz_mm"
        points[name] = np.asarray(chk.value(vec, Field("vector", length=3), key), float)

    def arr(key, scale=1.0):
        return np.array([j[key] for j in js], float) * scale

    pris = np.array([j["type"] == "prismatic" for j in js], bool)
    readings = _readings_table(chk, top["readings"], n, pris)
    F0 = np.eye(4)
    F0[:3, :3] = rpy_matrix(np.asarray(base["frame0_rpy_deg"], float) * DEG)
    F0[:3, 3] = base["frame0_xyz_mm"]
    return Robot(
        name=rob["name"],
        a_mm=arr("a_mm"), d_mm=arr("d_mm"), alpha_rad=arr("alpha_deg", DEG),
        theta_offset_rad=arr("theta_offset_deg", DEG), beta_rad=arr("beta_deg", DEG),
        hayati=np.array([j["hayati"] for j in js], bool),
        limits_rad=np.array([np.array(j["limits_deg"]) * DEG if j["type"] == "revolute" else j["limits_mm"]
                             for j in js], float),
        gear_ratio=arr("gear_ratio"), counts_per_rev=arr("encoder_counts_per_rev"),
        mass_kg=arr("mass_kg"), com_mm=np.array([j["com_mm"] for j in js], float),
        coupling=coupling, gravity_m_s2=np.asarray(rob["gravity_m_s2"], float),
        base_xyz_mm=np.asarray(base["xyz_mm"], float), base_rpy_rad=np.asarray(base["rpy_deg"], float) * DEG,
        tool_points_mm=points, joint_names=tuple(names), tool_point_frames=frames, parent_frame=parent,
        variable_of=variable, source=chk.source, prismatic=pris, frame0_in_base=F0, **readings,
    )


def _tree_fields(chk: Checker, joints: list, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """``parent`` / ``shares`` / ``fixed`` of every joint table: the frame each link starts from and the link whose
    variable it turns with (see the module docstring)."""
    n = len(names)
    parent, variable = np.arange(n), np.arange(n)
    for k, (j, key) in enumerate(joints):
        if j["parent"]:
            if j["parent"] != "base" and j["parent"] not in names[:k]:
                chk.fail(f"{key}.parent", f"{j['parent']!r} is not an earlier joint (or base)")
            parent[k] = 0 if j["parent"] == "base" else names.index(j["parent"]) + 1
        if j["shares"] and j["fixed"]:
            chk.fail(key, "a link either shares a joint's variable or is fixed, not both")
        if j["shares"]:
            if j["shares"] not in names[:k]:
                chk.fail(f"{key}.shares", f"{j['shares']!r} is not an earlier joint")
            variable[k] = names.index(j["shares"])
        if j["fixed"]:
            variable[k] = -1
    return parent, variable


def _readings_table(chk: Checker, t: dict, n: int, pris: np.ndarray) -> dict:
    """``[readings]``: ``names`` (m), ``matrix`` (n x m: joint = matrix @ readings + offset), ``offset`` (n; degrees,
    mm for a prismatic joint).  Written by :func:`robot_to_toml` for descriptions with mimic joints or reading
    conventions."""
    if not t:
        return {}
    if not isinstance(t, dict) or set(t) - {"names", "matrix", "offset"}:
        chk.fail("readings", "keys are names, matrix and offset")
    names = t.get("names")
    if not isinstance(names, list) or not names or not all(isinstance(x, str) for x in names):
        chk.fail("readings.names", "must be a list of reading names")
    M = np.asarray(chk.value(t.get("matrix"), Field("matrix"), "readings.matrix"), float)
    if M.shape != (n, len(names)):
        chk.fail("readings.matrix", f"must be {n} x {len(names)} (joints x readings)")
    off = np.asarray(chk.value(t.get("offset", [0.0] * n), Field("vector", length=n), "readings.offset"), float)
    return {"reading_names": tuple(names), "reading_matrix": M,
            "reading_offset": off * np.where(pris, 1.0, DEG)}


def robot_to_toml(robot: Robot) -> str:
    """Write a robot description back as TOML (used for identified robots); round-trips through :func:`parse_robot`."""
    def num(x: float) -> str:
        return repr(float(x))

    def vec(v) -> str:
        return "[" + ", ".join(num(x) for x in v) + "]"

    lines = ["# robot description written by robocal", "[robot]", f"name = {robot.name!r}".replace("'", '"'),
             f"gravity_m_s2 = {vec(robot.gravity_m_s2)}", ""]
    for i in range(robot.n):
        lines += [
            "[[joint]]",
            f'name = "{robot.joint_names[i] if robot.joint_names else f"j{i + 1}"}"',
            f'type = "{"prismatic" if robot.prismatic[i] else "revolute"}"',
            f"a_mm = {num(robot.a_mm[i])}",
            f"d_mm = {num(robot.d_mm[i])}",
            f"alpha_deg = {num(robot.alpha_rad[i] / DEG)}",
            f"theta_offset_deg = {num(robot.theta_offset_rad[i] / DEG)}",
            f"beta_deg = {num(robot.beta_rad[i] / DEG)}",
            f"hayati = {'true' if robot.hayati[i] else 'false'}",
            (f"limits_mm = {vec(robot.limits_rad[i])}" if robot.prismatic[i]
             else f"limits_deg = {vec(robot.limits_rad[i] / DEG)}"),
            f"gear_ratio = {num(robot.gear_ratio[i])}",
            f"encoder_counts_per_rev = {int(robot.counts_per_rev[i])}",
            f"mass_kg = {num(robot.mass_kg[i])}",
            f"com_mm = {vec(robot.com_mm[i])}",
        ]
        pf, var = robot.parent_frame[i], robot.variable_of[i]
        if pf != i:
            lines.append(f'parent = "{"base" if pf == 0 else robot.joint_names[pf - 1]}"')
        if var < 0:
            lines.append("fixed = true")
        elif var != i:
            lines.append(f'shares = "{robot.joint_names[var]}"')
        lines.append("")
    lines += ["[coupling]", "matrix = [" + ", ".join(vec(r) for r in robot.coupling) + "]", ""]
    lines += ["[base]", f"xyz_mm = {vec(robot.base_xyz_mm)}", f"rpy_deg = {vec(robot.base_rpy_rad / DEG)}"]
    F0 = robot.frame0_in_base
    if not np.allclose(F0, np.eye(4)):
        lines += [f"frame0_xyz_mm = {vec(F0[:3, 3])}", f"frame0_rpy_deg = {vec(rpy_from_matrix(F0[:3, :3]) / DEG)}"]
    lines.append("")
    if not robot.readings_are_joints or tuple(robot.reading_names) != tuple(robot.joint_names):
        lines += ["[readings]", "names = [" + ", ".join(f'"{x}"' for x in robot.reading_names) + "]",
                  "matrix = [" + ", ".join(vec(r) for r in robot.reading_matrix) + "]",
                  f"offset = {vec(robot.reading_offset / robot.edge_scale)}", ""]
    def point(k, v):
        f = robot.tool_point_frames.get(k, robot.n)
        if f == robot.n:
            return f"{_toml_key(k)} = {vec(v)}"
        link = "base" if f == 0 else robot.joint_names[f - 1]
        return f'{_toml_key(k)} = {{ link = "{link}", xyz_mm = {vec(v)} }}'
    lines += ["[tool.points]"] + [point(k, v) for k, v in robot.tool_points_mm.items()]
    return "\n".join(lines) + "\n"


def _toml_key(key: str) -> str:
    """A TOML key: bare when it can be (letters, digits, ``_``, ``-``), else quoted (a target named ``marker@x``)."""
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else '"' + key.replace("\\", "\\\\").replace('"', '\\"') + '"'
