"""The gravity-loaded backlash candidates of the diagnosis: a grid over the preload and the lumped tool mass.

:mod:`calib.effects.backlash_gravity` puts each pose on one side of the play: the side its load torque pushes it to
where that torque exceeds the preload, the side of the last approach elsewhere.  The preload and the end-effector's
lumped mass (where the data give no payload) only decide which poses rest on which side, so the point moves in steps
with them and no least-squares step can fit them.  They are searched as a transmission error's order is: every grid
point is a candidate of its own, ranked by its held-out score, and the multiple-test correction counts each.

The grid is made from the data: per joint and tool mass, preloads between the sorted load torques of the poses at
the quantiles :data:`PRELOAD_QUANTILES` (a preload equal to some pose's torque would let a refit of the geometry flip
that pose); tool masses are :data:`TOOL_MASS_SHARES` of the robot's link mass.  Grid points that put every pose on
the same sides as another (or as the plain backlash) are one candidate.  The torques are those of the geometric
fit (the tool point matters: a nominal tool point on a wrist axis carries no torque about it).
"""
from __future__ import annotations

import numpy as np

from calib.effects import make_effect

from .candidate import Candidate
from .data import DiagnosisData

#: where the preloads are placed among the poses' load torques (0: play held by gravity alone)
PRELOAD_QUANTILES = tuple(np.round(np.arange(0.0, 0.951, 0.05), 2))
#: lumped end-effector masses tried where the data give no payload, as shares of the robot's link mass
TOOL_MASS_SHARES = (0.0, 0.03, 0.1)
#: a side pattern is offered only when at least this share of the rows are off its most common side
MIN_OTHER_SIDE = 0.05
#: a joint whose load torque stays below this (N m) at every pose is not offered (a vertical axis)
MIN_TORQUE_NM = 1e-3


def preloads(tau: np.ndarray) -> list[float]:
    """Preloads between consecutive sorted |torques| at :data:`PRELOAD_QUANTILES` (0 for the first)."""
    a = np.sort(np.abs(tau))
    out = []
    for qv in PRELOAD_QUANTILES:
        k = int(round(qv * len(a)))
        out.append(0.0 if k == 0 else float(0.5 * (a[k - 1] + a[min(k, len(a) - 1)])))
    return out


def _balanced(side: np.ndarray) -> bool:
    """Whether the rows off the most common side are at least :data:`MIN_OTHER_SIDE` of them (and 3): sides
    constant but for a few rows are an offset (the geometry's) and a few rows' noise, and a fold may see none."""
    _, counts = np.unique(side, return_counts=True)
    return len(side) - counts.max() >= max(3, MIN_OTHER_SIDE * len(side))


def tool_masses(data: DiagnosisData) -> tuple[float, ...]:
    """The lumped masses to try: none when the data give the payload (then it is known), else shares of the
    robot's link mass."""
    if data.has.get("payload") or np.any(data.ctx.payload_kg != 0):
        return (0.0,)
    total = float(np.sum(data.robot.mass_kg))
    return tuple(sorted({round(s * total, 3) for s in TOOL_MASS_SHARES}))


def gravity_backlash_candidates(data: DiagnosisData, theta: np.ndarray | None, skipped: list[str]) -> list[Candidate]:
    """The grid of gravity-loaded backlash candidates on every revolute joint with a load torque (see the module
    docstring); joints left out are noted in ``skipped``."""
    robot = data.robot
    model = data.model([make_effect("backlash_gravity", 1)])
    th = model.nominal if theta is None else np.concatenate([np.asarray(theta, float)[: model.P - 1], [0.0]])
    if not np.any(robot.mass_kg > 0) and not np.any(data.ctx.payload_kg):
        skipped.append("backlash_gravity: the robot description has no masses and the data carries no payload")
        return []
    ev = model.evaluate(data.q_rad, data.ctx, th)
    tau0, per_kg = ev.loads.joint_torque_nm, ev.loads.tool_torque_per_kg
    out, flat = [], []
    for j in (k for k in range(1, robot.n + 1) if robot.variable_of[k - 1] == k - 1):     # a joint, not a branch link
        if robot.prismatic[j - 1]:
            continue
        seen = {tuple(-data.ctx.direction[:, j - 1])}         # the plain backlash's sides
        before = len(out)
        for m in tool_masses(data):
            tau = tau0[:, j - 1] + m * per_kg[:, j - 1]
            if np.max(np.abs(tau)) < MIN_TORQUE_NM:
                continue
            known = np.any(data.ctx.direction[:, j - 1] != 0)   # else only gravity can set the side: preload 0
            for p in preloads(tau) if known else [0.0]:
                side = tuple(np.where(np.abs(tau) > p, np.sign(tau), -data.ctx.direction[:, j - 1]))
                if side in seen or not _balanced(np.array(side)):
                    continue
                seen.add(side)
                out.append(Candidate("backlash_gravity", j, free=("width_rad",), preload_nm=float(p),
                                     tool_mass_kg=m))
        if len(out) == before:
            flat.append(j)
    if flat:
        skipped.append(f"backlash_gravity on joints {', '.join(map(str, flat))}: no load torque about them, or it "
                       f"puts every pose on the sides of the plain backlash")
    return out
