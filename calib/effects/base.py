"""What every effect shares: the pose conditions, the loads, the :class:`Effect` base class and the registry.

An effect class is registered once with :func:`register_effect`; everything that builds an effect from its kind name
(the model JSON, the twin scenario's ``[[effect]]`` tables, ``--effect kind:args`` on identify, the diagnosis
candidates) looks the class up in :data:`EFFECTS` (see :mod:`calib.effects.registry`), so adding an effect is one
module in this package plus its tests.

An effect class says, besides its physics:

* ``scenario_fields`` and :meth:`Effect.from_table`: its ``[[effect]]`` table in a scenario file (file units, deg);
* ``options`` / :meth:`Effect.option_values`: the structural settings beyond the joint (order, source joint,
  reference temperature) that fix its parameter list; they travel in the model JSON and the ``--effect`` text;
* :meth:`Effect.zero`: the effect at zero (or negligible) magnitude, the start of an identification.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

_DEG = np.pi / 180.0


@dataclass
class PoseContext:
    """What each of N poses was measured under, beyond its joint readings.  Arrays over poses; zeros by default."""

    n_poses: int
    n_joints: int = 6
    direction: np.ndarray | None = None        # (N, n) +1/-1: sign of each joint's last motion; 0 unknown
    load_direction: np.ndarray | None = None   # (N, n) +1 loading, -1 unloading, 0 unknown
    payload_kg: np.ndarray | None = None       # (N,) mass hanging at the tool point
    tool_force_n: np.ndarray | None = None     # (N, 3) external force at the tool point, measurement frame
    joint_torque_nm: np.ndarray | None = None  # (N, n) torque applied directly to joints (compliance loads)
    temperature_c: np.ndarray | None = None    # (N,)
    time_s: np.ndarray | None = None           # (N,)
    # forces at points fixed on links (hung masses: mass x the model's gravity), K of them per pose (contract C2)
    point_force_link: np.ndarray | None = None  # (K,) int: frame the point is fixed in (0 base, j = link j)
    point_force_mm: np.ndarray | None = None    # (N, K, 3) the point, in that frame
    point_force_n: np.ndarray | None = None     # (N, K, 3) the force, in the measurement frame

    def __post_init__(self):
        N, n = self.n_poses, self.n_joints
        for name, shape in (("direction", (N, n)), ("load_direction", (N, n)), ("payload_kg", (N,)),
                            ("tool_force_n", (N, 3)), ("joint_torque_nm", (N, n)), ("temperature_c", (N,)),
                            ("time_s", (N,))):
            v = getattr(self, name)
            if v is None:
                v = np.full(shape, 20.0 if name == "temperature_c" else 0.0)
            else:               # a copy of the caller's array (a twin's context is made every state: no broadcast)
                v = np.asarray(v, float)
                v = v.copy() if v.shape == shape else np.broadcast_to(v, shape).copy()
            setattr(self, name, v)
        link = np.zeros(0, int) if self.point_force_link is None else np.asarray(self.point_force_link)
        if link.ndim != 1 or (link.size and (np.any(link != np.round(link)) or link.min() < 0 or link.max() > n)):
            raise ValueError(f"point_force_link must be frame indices 0..{n}, got {self.point_force_link!r}")
        self.point_force_link = link.astype(int)
        K = link.size
        for name in ("point_force_mm", "point_force_n"):
            v = getattr(self, name)
            if v is None:
                v = np.zeros((N, K, 3))
            else:
                v = np.asarray(v, float)
                v = v.copy() if v.shape == (N, K, 3) else np.broadcast_to(v, (N, K, 3)).copy()
            setattr(self, name, v)

    def subset(self, idx) -> "PoseContext":
        pick = {k: getattr(self, k)[idx] for k in ("direction", "load_direction", "payload_kg", "tool_force_n",
                                                      "joint_torque_nm", "temperature_c", "time_s",
                                                      "point_force_mm", "point_force_n")}
        n_new = len(pick["payload_kg"])
        return PoseContext(n_new, self.n_joints, point_force_link=self.point_force_link, **pick)


@dataclass
class Loads:
    """Quantities some effects need, computed once per forward pass by the model."""

    joint_torque_nm: np.ndarray       # (N, n) torque about each joint axis (gravity + payload + tool force + applied)
    tip_force_n: np.ndarray           # (N, n, 3) force carried at the end of each link (frame j origin)
    dtau_dgeo: np.ndarray | None = None   # (N, n, P_geometric) d torque / d geometric parameter, when asked
    # the point forces of the pose context, placed: for effects that load a link along its length
    point_force_n: np.ndarray | None = None   # (N, K, 3) N, measurement frame
    point_at_mm: np.ndarray | None = None     # (N, K, 3) where each acts, measurement frame
    point_link: np.ndarray | None = None      # (K,) frame each point is fixed in
    joint_moment_nm: np.ndarray | None = None  # (N, n, 3) moment about joint j's origin (or pivot) of all it carries
    tool_torque_per_kg: np.ndarray | None = None  # (N, n) N m about joint j of 1 kg at the tool point (0 if not carried)
    #: (n, n+1) bool: frame f moves with joint j's variable (below its link, or a branch sharing it): which rows'
    #: points a joint's deflection moves, on a tree as on a chain (:meth:`calib.robot.Robot.frames_moved`)
    frames_moved: np.ndarray | None = None


@dataclass
class ElementMotions:
    """The elementary motions of the chain at one evaluation, for an effect whose displacement is expressed in frames
    the geometry moves (:meth:`Effect.geometry_jacobian`): each geometric parameter owns one motion (a rotation about
    ``axis`` through ``origin_mm``, or a translation along it), which moves frame f rigidly when ``moves[f, e]``."""

    axis: np.ndarray           # (N, E, 3)
    origin_mm: np.ndarray      # (N, E, 3)
    rotation: np.ndarray       # (E,) bool
    moves: np.ndarray          # (n+1, E) bool
    point: np.ndarray          # (N, 3, E) d evaluated point / d element (the point's own element Jacobian)


class JointNumber(int):
    """Marks an option that names a joint (1..n), e.g. the source joint of a cross coupling: checked like ``joint``."""


class Effect:
    """Base class.  Subclasses set ``kind``, ``stage`` and implement the stage's method.

    Stages (see :mod:`calib.model`): ``joint`` -> :meth:`joint_delta`; ``geometry`` -> :meth:`geometry_delta` and
    :meth:`geometry_chain`; ``point`` -> :meth:`point_delta`.
    """

    kind: ClassVar[str] = ""
    stage: ClassVar[str] = "joint"
    needs_loads: ClassVar[bool] = False        # the model computes :class:`Loads` for it
    torque_driven: ClassVar[bool] = False      # implements :meth:`torque_gain` (deflection follows the torque)
    #: point stage: the displacement follows the moment vectors some joints carry (:meth:`moment_joints`,
    #: :meth:`moment_gain`, :meth:`geometry_jacobian`, :meth:`moment_term_size`)
    moment_driven: ClassVar[bool] = False
    #: ``load`` stage: adds bodies (forces at points on links) to the loads every torque- or moment-driven effect
    #: sees (:meth:`bodies`); it moves no point itself
    adds_bodies: ClassVar[bool] = False
    has_joint: ClassVar[bool] = True           # acts on one joint (``joint`` required in tables, JSON and text)
    #: joint stage: the change and its derivative sit in the column of ``joint`` alone (the Jacobian then takes
    #: that joint's column times the derivative's row, not a product over every joint: a 19-joint tree's 1184
    #: candidates are written that way each round)
    own_joint_only: ClassVar[bool] = False
    #: structural settings beyond the joint, name -> type (int or float), in the order of the ``--effect`` text
    options: ClassVar[dict[str, type]] = {}
    #: how many of ``options`` the ``--effect`` text must give (the rest have defaults in :meth:`zero`)
    text_required: ClassVar[int] = 0
    #: the keys of its ``[[effect]]`` table in a scenario file (``calib.tomlspec.Field``), besides type/enabled
    scenario_fields: ClassVar[dict[str, Any]] = {}
    #: parameters that are positive by physics (a compliance, a mass): a negative estimate absorbs another error
    positive_params: ClassVar[tuple[str, ...]] = ()
    #: the pose condition whose variation makes it visible (a key of ``calib.effects.drivers.DRIVERS``), None when
    #: the poses' geometry alone does; identify refuses and the diagnosis skips an effect whose driver is constant
    driven_by: ClassVar[str | None] = None

    def __init__(self, joint: int | None, values: dict[str, float]):
        self.joint = joint                       # 1-based joint the effect disturbs, or None
        self.values = np.array([values[k] for k in self.param_names], float)

    # -- construction (used through calib.effects.registry) --------------------------------------------------------
    @classmethod
    def zero(cls, joint: int | None = None, **options) -> "Effect":
        """The effect at zero (or negligible) magnitude with the given structure: the start of an identification."""
        raise NotImplementedError

    @classmethod
    def from_table(cls, c: dict) -> "Effect":
        """The effect from a checked scenario ``[[effect]]`` table (file units: degrees, N m, N mm^2)."""
        raise NotImplementedError

    def option_values(self) -> dict[str, Any]:
        """This instance's structural settings (the keys of ``options``)."""
        return {}

    # -- naming ----------------------------------------------------------------------------------------------------
    @property
    def label(self) -> str:
        return f"{self.kind}.j{self.joint}" if self.joint is not None else self.kind

    @property
    def param_names(self) -> tuple[str, ...]:
        raise NotImplementedError

    def qualified_names(self) -> list[str]:
        return [f"{self.label}.{p}" for p in self.param_names]

    def finding_label(self) -> str:
        """How the diagnosis names this effect in a finding (a kind with structure overrides it)."""
        return f"{self.kind} j{self.joint}" if self.joint is not None else self.kind

    def edge_parameters(self, values: dict[str, float], sigmas: dict[str, float], free) -> dict[str, Any]:
        """The estimated parameters ``free`` in edge units for reports and JSON: radians as degrees, each with
        ``<name>_sigma``.  A kind whose readers expect other quantities (a stiffness, an amplitude) overrides it."""
        out: dict[str, Any] = {}
        for k in free:
            v, s = values[k], sigmas[k]
            if k.endswith("_rad"):
                k, v, s = k[:-4] + "_deg", v / _DEG, s / _DEG
            out[k] = float(v)
            out[f"{k}_sigma"] = float(s)
        return out

    def describe(self) -> str:
        parts = ", ".join(f"{k}={v:.6g}" for k, v in zip(self.param_names, self.values))
        return f"{self.label}({parts})"

    # -- physics ---------------------------------------------------------------------------------------------------
    def joint_delta(self, q, ctx: PoseContext, loads: Loads | None, values):
        """joint stage: (N, n) change of the joint angles and its derivative (N, n, K) w.r.t. ``values``."""
        raise NotImplementedError

    def torque_gain(self, q, ctx: PoseContext, loads: Loads, values):
        """torque-driven joint effects: (N, n) d delta / d tau (for the chain rule through the loads)."""
        raise NotImplementedError

    def geometry_delta(self, params, length_idx, ctx: PoseContext, values):
        """geometry stage: (N, P) change of the geometric parameters and its derivative (N, P, K)."""
        raise NotImplementedError

    def geometry_chain(self, J_geo, length_idx, ctx: PoseContext, values):
        """geometry stage: the Jacobian w.r.t. the geometric parameters (N, 3, P) given the one w.r.t. the changed
        parameters: ``J_geo @ (I + d delta / d params)``.  The default is a change that does not depend on them."""
        return J_geo

    def point_delta(self, fp, point, loads: Loads | None, values):
        """point stage: (N, 3) displacement of the point and its derivative (N, 3, K)."""
        raise NotImplementedError

    # -- moment-driven point effects (lateral compliance) -------------------------------------------------------------
    def moment_joints(self) -> list[int]:
        """The joints (0-based) whose carried moment (``Loads.joint_moment_nm``) drives the displacement."""
        return [self.joint - 1]

    def moment_pivots_mm(self) -> list[float]:
        """Where along each of :meth:`moment_joints`'s axes the moment is taken (mm from the origin of the frame
        the joint's link starts from): the point the joint bends about (``Loads.joint_moment_nm`` is about it)."""
        return [0.0] * len(self.moment_joints())

    def moment_gain(self, fp, point, loads: Loads, values):
        """(N, 3, k, 3) d displacement / d moment of each of :meth:`moment_joints` (mm per N m): the chain rule
        through the loads (the moments change with the geometry and with identified bodies)."""
        raise NotImplementedError

    def geometry_jacobian(self, fp, point, loads: Loads, values, motions: ElementMotions):
        """(N, 3, E) the displacement's change with each geometric element, the moments held: the frames it is
        expressed in and the lever arms move with the geometry (the moments' own change is added by the model)."""
        raise NotImplementedError

    def moment_term_size(self, loads: Loads, values) -> float:
        """The largest rotation (rad) the moments cause: the relative size of :meth:`geometry_jacobian` and of the
        moments' change in the geometric columns (the rule of :func:`calib.model.torque_term_matters`)."""
        raise NotImplementedError

    # -- load-stage effects (identified masses) -----------------------------------------------------------------------
    def bodies(self, fp, values):
        """Bodies the effect adds to the loads: positions (N, K, 3) mm in the measurement frame, masses (K,) kg (the
        force is mass x the model's gravity), d masses / d values (K, P_effect), and the frame (0..n) each is fixed
        in (a force moves with that frame; every joint moving it carries it)."""
        raise NotImplementedError


#: kind name -> effect class, filled by :func:`register_effect` as the kind modules are imported
EFFECTS: dict[str, type[Effect]] = {}


def register_effect(cls: type[Effect]) -> type[Effect]:
    """Class decorator: make an effect kind known to every builder (once per kind)."""
    if not cls.kind:
        raise TypeError(f"{cls.__name__} has no kind")
    if EFFECTS.get(cls.kind, cls) is not cls:
        raise TypeError(f"effect kind {cls.kind!r} registered twice ({EFFECTS[cls.kind].__name__}, {cls.__name__})")
    EFFECTS[cls.kind] = cls
    return cls
