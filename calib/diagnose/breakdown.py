"""Where the gap lies: held-out residuals grouped by the conditions of each pose.

Factors: each joint's angle (quartiles), the workspace region (reach from the base axis and height, thirds), payload,
approach direction per joint, time and temperature (quartiles), and what a session adds (procedure, sighting
geometry).  Each factor gets Kruskal-Wallis tests across its groups, of the residual lengths and of the residual expressed as an
equivalent error of each joint (``e_j = J_j . r / |J_j|^2``, J_j the tool point's motion per unit of joint j): a
backlash moves the point one way or the other with the approach direction, which leaves the residual *length* alike in
both groups but splits ``e_j`` cleanly.  The factor's p-value is the smallest of these, Bonferroni-corrected for their
number, and names the statistic.  A small p-value says the gap depends on that condition, which points at the effect
(a joint's angle -> transmission error, direction -> backlash, temperature -> thermal drift, reach or payload ->
compliance).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.distributions import kruskal_p
from calib.units import DEG

from .data import DiagnosisData


@dataclass
class Group:
    label: str
    n: int
    rms_before_mm: float
    rms_after_mm: float
    max_before_mm: float


@dataclass
class Factor:
    name: str
    groups: list[Group]
    p_value: float            # Kruskal-Wallis (smallest over the statistics, Bonferroni-corrected)
    statistic: str = "residual length"

    def as_dict(self) -> dict:
        return {"factor": self.name, "p_value": self.p_value, "statistic": self.statistic,
                "groups": [{"label": g.label, "n": g.n, "rms_geometric_mm": g.rms_before_mm,
                            "rms_final_mm": g.rms_after_mm, "max_geometric_mm": g.max_before_mm}
                           for g in self.groups]}


def _rms(x):
    return float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")


Stats = list[tuple[str, np.ndarray]]       # the statistics tested per factor: (name, value per pose)


def _factor(name: str, keys: np.ndarray, labels: list[str], before: np.ndarray, after: np.ndarray,
            tests: Stats) -> Factor | None:
    groups, sels = [], []
    for k, lab in enumerate(labels):
        sel = keys == k
        if sel.sum() == 0:
            continue
        groups.append(Group(lab, int(sel.sum()), _rms(before[sel]), _rms(after[sel]), float(before[sel].max())))
        sels.append(sel)
    if len(groups) < 2:
        return None
    best, which = 1.0, "residual length"
    for sname, vals in tests:
        p = kruskal_p(*[vals[s] for s in sels])     # NaN when all values are identical: no evidence
        if p == p and p < best:
            best, which = p, sname
    return Factor(name, groups, min(1.0, best * len(tests)), which)


def _binned(name: str, x: np.ndarray, nbins: int, unit: str, fmt: str, before, after, tests: Stats) -> Factor | None:
    if np.ptp(x) <= 0:
        return None
    edges = np.unique(np.quantile(x, np.linspace(0, 1, nbins + 1)))
    if len(edges) < 3:
        return None
    keys = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    labels = [f"{edges[i]:{fmt}}..{edges[i + 1]:{fmt}} {unit}" for i in range(len(edges) - 1)]
    return _factor(name, keys, labels, before, after, tests)


def _categorical(name: str, values, before, after, tests: Stats) -> Factor | None:
    vals = [str(v) for v in values]
    labels = sorted(set(vals))
    if len(labels) < 2:
        return None
    keys = np.array([labels.index(v) for v in vals])
    return _factor(name, keys, labels, before, after, tests)


def breakdown(data: DiagnosisData, res_before_mm: np.ndarray, res_after_mm: np.ndarray,
              base_xyz_mm: np.ndarray, up: np.ndarray | None = None,
              joint_jacobian: np.ndarray | None = None) -> list[Factor]:
    """Factors over the held-out residuals of the geometric model (before) and the final model (after).

    ``base_xyz_mm`` and ``up`` (unit vertical of the robot base in the measurement frame) place the workspace;
    ``joint_jacobian`` (N, 3, n), the tool point's motion per unit of each joint, gives the equivalent joint errors.
    """
    before = np.linalg.norm(res_before_mm, axis=1)
    after = np.linalg.norm(res_after_mm, axis=1)
    r = data.robot
    # signed components too: a shift of part of the poses (the instrument moved) is half absorbed by the fit and
    # leaves residuals of equal length but opposite sign
    tests: Stats = [("residual length", before)] + [(f"residual {c}", res_before_mm[:, i]) for i, c in enumerate("xyz")]
    # a joint's own link only: a tree's branch link turns with its joint (its motion adds to the joint's) and a fixed
    # link has no variable
    own = [j for j in range(r.n) if r.variable_of[j] == j]
    if joint_jacobian is not None:
        if not r.readings_are_joints or r.is_tree:
            joint_jacobian = np.matmul(joint_jacobian, r.variable_spread())
        for j in own:
            Jj = joint_jacobian[:, :, j]
            # a joint whose axis passes near the point moves it little: floor the gain at 10 mm per rad (mm)
            den = np.maximum(np.sum(Jj ** 2, axis=1), 100.0)
            tests.append((f"joint {j + 1} equivalent error", np.sum(Jj * res_before_mm, axis=1) / den))
    out: list[Factor | None] = []
    for j in own:
        x = data.q_rad[:, j]
        if r.prismatic[j]:
            out.append(_binned(f"joint {j + 1} position", x, 4, "mm", ".0f", before, after, tests))
        else:
            out.append(_binned(f"joint {j + 1} angle", x / DEG, 4, "deg", ".0f", before, after, tests))
    up = np.array([0.0, 0.0, 1.0]) if up is None else up
    rel = data.points_mm - base_xyz_mm
    h = rel @ up
    reach = np.linalg.norm(rel - h[:, None] * up, axis=1)
    out.append(_binned("workspace reach from the base axis", reach, 3, "mm", ".0f", before, after, tests))
    out.append(_binned("workspace height above the base", h, 3, "mm", ".0f", before, after, tests))
    if data.has.get("payload"):
        p = data.ctx.payload_kg
        out.append(_categorical("payload (kg)", [f"{v:g}" for v in p], before, after, tests) if len(np.unique(p)) <= 6
                   else _binned("payload", p, 4, "kg", ".2f", before, after, tests))
    if data.has.get("direction"):
        for j in own:
            d = data.ctx.direction[:, j]
            if np.ptp(d) > 0:
                out.append(_categorical(f"joint {j + 1} approach direction",
                                        ["+" if v > 0 else "-" if v < 0 else "?" for v in d], before, after, tests))
    if data.has.get("time"):
        out.append(_binned("time", data.ctx.time_s, 4, "s", ".0f", before, after, tests))
    if data.has.get("temperature"):
        out.append(_binned("temperature", data.ctx.temperature_c, 4, "degC", ".1f", before, after, tests))
    for name, vals in data.labels.items():
        out.append(_categorical(name, vals, before, after, tests))
    for name, vals in data.numeric.items():
        out.append(_binned(name, np.asarray(vals, float), 3, "", ".1f", before, after, tests))
    return [f for f in out if f is not None]
