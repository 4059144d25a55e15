"""Several targets per pose (reflectors, markers) fitted jointly: which tool point each row measures.

The description names the tool points; the first one a data set uses is the *reference* (the chain's ``tool.*``
parameters), every other one is the reference plus a :class:`calib.effects.target_offset.TargetOffset`, so one
identification estimates the chain and all targets from every row.  After identification each target's point is
written back under its own name (:func:`identified_tool_points`), so ``evaluate`` and ``locate`` find them by name.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .effects.base import PoseContext
from .effects.station_offset import StationOffset
from .effects.target_offset import TargetOffset


@dataclass
class TargetContext(PoseContext):
    """A :class:`PoseContext` that also says which tool point (index into the robot's tool points) each row measures."""

    target: np.ndarray | None = None           # (N,) int
    station: np.ndarray | None = None          # (N,) int: index of the instrument set-up (0: the reference)

    def __post_init__(self):
        super().__post_init__()
        self.target = np.zeros(self.n_poses, int) if self.target is None else np.asarray(self.target, int)
        self.station = np.zeros(self.n_poses, int) if self.station is None else np.asarray(self.station, int)

    def subset(self, idx) -> "TargetContext":
        base = super().subset(idx)
        keep = {k: getattr(base, k) for k in base.__dataclass_fields__ if k not in ("target", "station")}
        return TargetContext(**keep, target=self.target[idx], station=self.station[idx])


def reference_name(names: list[str]) -> str:
    """The tool point the chain's ``tool.*`` parameters are (the choice of :meth:`calib.robot.Robot.tool_point`)."""
    return "P" if "P" in names and len(names) > 1 else names[0]


def order_targets(robot, names_used: list[str]):
    """The robot with only the tool points the data uses, the reference first."""
    pts = robot.tool_points_mm
    used = list(dict.fromkeys(names_used))
    ref = reference_name(used)
    return robot.with_tool({k: pts[k] for k in [ref] + [u for u in used if u != ref]})


def target_effects(robot, names_used: list[str]) -> list[TargetOffset]:
    """One offset effect per extra target, started at the description's offset from the reference."""
    pts = list(robot.tool_points_mm.items())
    ref = pts[0][1]
    used = set(names_used)
    return [TargetOffset(k, pts[k][1] - ref) for k in range(1, len(pts)) if pts[k][0] in used]


def with_targets(robot, names_used: list[str]) -> tuple:
    """A tool point per target: the robot whose tool points are the targets ``names_used`` (the reference first) and
    the offset effects of the other targets, to be fitted jointly with the chain.  The one way identify and diagnose
    model several targets per pose."""
    robot = order_targets(robot, names_used)
    return robot, target_effects(robot, names_used)


def target_index(robot, target: list[str] | None, n: int) -> np.ndarray:
    names = list(robot.tool_points_mm)
    if target is None:
        return np.zeros(n, int)
    return np.array([names.index(t) for t in target], int)


def station_index(station: list[str] | None, n: int, names: list[str] | None = None) -> tuple[np.ndarray, list[str]]:
    """Index of each row's station among ``names`` (a model's :attr:`~calib.model.MeasurementModel.stations`: 0 the
    reference set-up), matched by name; -1 for a station not among them.  ``names`` None (new data, or a model file
    from before the names were kept): the sorted station names of the rows.  ``names`` empty (a model identified
    without a station column): rows of one station are that set-up."""
    if station is None:
        return np.zeros(n, int), list(names or [])
    if names is None:
        names = sorted(set(station))
    elif not names and len(set(station)) == 1:
        return np.zeros(n, int), [station[0]]
    pos = {s: k for k, s in enumerate(names)}
    return np.array([pos.get(s, -1) for s in station], int), list(names)


def station_effects(names: list[str]) -> list:
    """One base-offset effect per station after the first (fitted jointly with the chain)."""
    return [StationOffset(k) for k in range(1, len(names))]


def identified_tool_points(model, theta) -> dict[str, np.ndarray]:
    """Every tool point of the model's robot after identification: the reference from ``tool.*``, the others from
    their offsets (a point without an offset effect keeps its described position)."""
    kin = model.kin
    i = kin.index["tool.x_mm"]
    tool = np.asarray(theta[i:i + 3], float)
    names = list(model.robot.tool_points_mm) or ["P"]
    ref = reference_name(names)
    offsets = {e.target: theta[s] for e, s in zip(model.effects, model.effect_slices) if isinstance(e, TargetOffset)}
    out = {}
    for k, name in enumerate(names):
        if name == ref:
            out[name] = tool
        else:
            out[name] = tool + offsets[k] if k in offsets else model.robot.tool_points_mm[name]
    return out
