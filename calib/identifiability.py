"""Identifiability of a parameter set from a given experiment, before anything is reported.

The weighted Jacobian (rows whitened by the measurement covariance) is column-scaled so that units do not matter, and
its singular value decomposition says:

* the rank and the condition number;
* the parameter *combinations* the experiment cannot determine (null space) and those it determines poorly (small
  singular values), written in words ("the shoulder offset d (j2.d_mm) and the base position X (base.x_mm) act
  alike");
* why, where a joint that barely moves is the cause (checked, not guessed: the combination becomes determinable when
  that joint's readings are spread over its range);
* an automatic treatment: the parameter that carries each undeterminable combination is fixed at its current value,
  one at a time, until the rest is full rank — so no variance of 1e12 is ever printed as a result.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

#: singular value ratio (column-scaled) below which a direction is not determinable in practice: it is held
HOLD_RTOL = 1e-4
#: below this the direction is exactly undeterminable (reported as such, not as "practically")
RANK_RTOL = 1e-9
#: ratio below which a kept direction is reported as weakly determined (condition number above 1/WEAK_RTOL)
WEAK_RTOL = 1e-2

_WHAT = {
    "theta_offset_rad": "zero offset", "d_mm": "offset d", "a_mm": "length a", "alpha_rad": "twist alpha",
    "beta_rad": "Hayati beta",
}
_BASE = {"x_mm": "base position X", "y_mm": "base position Y", "z_mm": "base position Z", "yaw_rad": "base yaw",
         "pitch_rad": "base pitch", "roll_rad": "base roll"}
_TOOL = {"x_mm": "tool point x", "y_mm": "tool point y", "z_mm": "tool point z"}
#: the thesis's names for the Puma's link parameters (Fig 3.5)
THESIS_NAMES = {"j2.a_mm": "upper arm a1", "j3.a_mm": "elbow offset a2", "j2.d_mm": "shoulder offset d1",
                "j3.d_mm": "shoulder offset d1 beyond the parallel axes", "j4.d_mm": "forearm d2",
                "j6.d_mm": "flange d3"}
_STATION = {"x_mm": "position X", "y_mm": "position Y", "z_mm": "height", "yaw_rad": "circle orientation",
            "tilt_x_rad": "levelling about X", "tilt_y_rad": "levelling about Y", "collimation_rad": "collimation",
            "trunnion_rad": "trunnion axis error", "index_rad": "vertical index error"}


def describe(name: str, joint_names: tuple[str, ...] | None = None) -> str:
    """A parameter in words, with its code name: ``shoulder offset d1 (j2.d_mm)``; with the description's
    ``joint_names`` (a robot that is not the thesis's Puma): ``joint 3 (elbow_joint) length a (j3.a_mm)``."""
    head, _, tail = name.partition(".")
    if joint_names and head.startswith("j") and head[1:].isdigit() and tail in _WHAT \
            and int(head[1:]) <= len(joint_names):
        return f"joint {head[1:]} ({joint_names[int(head[1:]) - 1]}) {_WHAT[tail]} ({name})"
    if name in THESIS_NAMES and not joint_names:
        return f"{THESIS_NAMES[name]} ({name})"
    head, _, tail = name.partition(".")
    if name == "B.x_mm":
        return f"the baseline L, i.e. the overall scale ({name})"
    if head.isupper() and tail in _STATION:
        return f"station {head} {_STATION[tail]} ({name})"
    if head == "base" and tail in _BASE:
        return f"{_BASE[tail]} ({name})"
    if head == "tool" and tail in _TOOL:
        return f"{_TOOL[tail]} ({name})"
    if head.startswith("j") and head[1:].isdigit() and tail in _WHAT:
        return f"joint {head[1:]} {_WHAT[tail]} ({name})"
    return name


@dataclass
class Combination:
    """A direction in parameter space: ``sum coef_i * scaled parameter_i``, with its singular value ratio."""

    coefficients: dict[str, float]
    ratio: float                          # singular value / largest singular value
    because: str = ""

    def words(self, joint_names: tuple[str, ...] | None = None) -> str:
        items = sorted(self.coefficients.items(), key=lambda kv: -abs(kv[1]))
        big = [describe(n, joint_names) for n, c in items if abs(c) >= 0.25 * abs(items[0][1])][:5]
        if len(big) == 1:
            text = (f"{big[0]} has no effect on the measurements" if self.ratio <= RANK_RTOL
                    else f"{big[0]} is poorly determined")
        verb = "cannot separate" if self.ratio <= HOLD_RTOL else "can hardly separate"
        if len(big) == 2:
            text = f"{verb} {big[0]} from {big[1]}"
        elif len(big) > 2:
            text = f"{verb} " + ", ".join(big[:-1]) + f" and {big[-1]}"
        return text + (f", because {self.because}" if self.because else "")


@dataclass
class Identifiability:
    names: list[str]
    rank: int
    condition: float
    singular_values: np.ndarray
    unidentifiable: list[Combination] = field(default_factory=list)
    weak: list[Combination] = field(default_factory=list)
    fixed: list[str] = field(default_factory=list)          # automatic treatment
    kept: list[str] = field(default_factory=list)
    weakest: list[Combination] = field(default_factory=list)   # the three smallest directions kept
    kept_condition: float = float("nan")

    def report(self, joint_names: tuple[str, ...] | None = None) -> list[str]:
        lines = [f"{len(self.names)} parameters, rank {self.rank}, condition number {self.condition:.3g} "
                 f"(column-scaled)"]
        for c in self.unidentifiable:
            what = "not identifiable" if c.ratio <= RANK_RTOL else f"not identifiable in practice (ratio {c.ratio:.1e})"
            lines.append(f"{what}: " + c.words(joint_names))
        for c in self.weak:
            lines.append(f"weakly identifiable (singular value ratio {c.ratio:.1e}): " + c.words(joint_names))
        if self.fixed:
            lines.append("held at their design values: " + ", ".join(self.fixed))
            lines.append(f"remaining {len(self.kept)} parameters: condition number {self.kept_condition:.3g}")
        return lines


def analyse(J: np.ndarray, names: list[str],
            rejacobian: Callable[[int], np.ndarray] | None = None,
            joint_ranges_rad: np.ndarray | None = None,
            prefer_fix: Callable[[str], int] | None = None) -> Identifiability:
    """Analyse the whitened Jacobian ``J`` (m, p) of the parameters ``names``.

    ``rejacobian(k)``, when given, recomputes J with joint k's readings spread over its range; a combination that it
    makes determinable is explained as "joint k barely moves".  ``prefer_fix(name)`` ranks which parameter of a
    combination to hold (lower first); ties go to the one with the largest coefficient.
    """
    m, p = J.shape
    norms = np.linalg.norm(J, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    Js = J / safe
    _, s, Vt = np.linalg.svd(Js, full_matrices=m < p)          # Vt must be p x p; U never needed in full
    smax = s[0] if s.size and s[0] > 0 else 1.0
    ratio = np.concatenate([s / smax, np.zeros(max(0, p - s.size))])
    rank = int(np.sum(ratio > RANK_RTOL))
    cond = float(smax / s[rank - 1]) if rank == p and rank > 0 else float("inf")
    out = Identifiability(list(names), rank, cond, s)

    # automatic treatment: hold one parameter per undeterminable direction until the rest is full rank
    keep = list(range(p))
    fixed: list[int] = []
    while keep:
        _, s_k, Vt_k = np.linalg.svd(Js[:, keep], full_matrices=m < len(keep))
        r_k = s_k / (s_k[0] if s_k.size and s_k[0] > 0 else 1.0)
        if len(s_k) == len(keep) and r_k[-1] > HOLD_RTOL:
            out.kept_condition = float(1.0 / r_k[-1])
            break
        v = Vt_k[-1]
        cand = [((prefer_fix(names[keep[k]]) if prefer_fix else 0), -abs(v[k]), k) for k in range(len(keep))
                if abs(v[k]) > 0.2 * np.max(np.abs(v))]
        _, _, k = min(cand)
        fixed.append(keep.pop(k))
    out.fixed = [names[i] for i in fixed]
    out.kept = [names[i] for i in keep]

    # the undeterminable directions, written on the held parameters: each holds one, plus what absorbs it
    if fixed:
        small = np.flatnonzero(ratio <= HOLD_RTOL)
        null = Vt[small].T                                              # (p, number held)
        basis = null @ np.linalg.pinv(null[fixed, :])                   # unit on each held parameter
        for col, f in zip(basis.T, fixed):
            coef = {names[k]: float(col[k]) for k in np.flatnonzero(np.abs(col) > 0.05)}
            v = col / np.linalg.norm(col)
            combo = Combination(coef, float(np.linalg.norm(Js @ v) / smax))
            if rejacobian is not None and joint_ranges_rad is not None:
                combo.because = _explain(v, combo.ratio, rejacobian, joint_ranges_rad, norms)
            out.unidentifiable.append(combo)
    # the weakest directions among the kept parameters (reported as weak below WEAK_RTOL)
    if keep:
        _, s_k, Vt_k = np.linalg.svd(Js[:, keep], full_matrices=False)
        r_k = s_k / smax
        for i in np.argsort(r_k)[:3]:
            v = np.zeros(p)
            v[keep] = Vt_k[i]
            coef = {names[k]: float(v[k]) for k in np.flatnonzero(np.abs(v) > 0.05)}
            combo = Combination(coef, float(r_k[i]))
            if rejacobian is not None and joint_ranges_rad is not None:
                combo.because = _explain(v, combo.ratio, rejacobian, joint_ranges_rad, norms)
            out.weakest.append(combo)
            if r_k[i] < WEAK_RTOL:
                out.weak.append(combo)
    return out


def _explain(v: np.ndarray, before: float, rejacobian, ranges: np.ndarray, norms: np.ndarray) -> str:
    """Which joint, if spread over its range, would make the direction ``v`` (scaled parameters) far better determined.

    Checked, not guessed: the direction's response ``|J v| / |J|`` (``before`` now) is recomputed with that joint's
    readings spread over its limits; a tenfold gain names the joint.
    """
    safe = np.where(norms > 0, norms, 1.0)
    for k in np.argsort(ranges):
        if ranges[k] > np.radians(30):
            break
        J2 = rejacobian(int(k)) / safe
        s2 = np.linalg.norm(J2, 2)
        if s2 > 0 and np.linalg.norm(J2 @ v) / s2 > 10 * before + 1e-6:
            return f"joint {k + 1} barely moves (range {np.degrees(ranges[k]):.1f} deg over the poses)"
    return ""
