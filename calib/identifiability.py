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

import re
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import names as naming

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
#: a prismatic joint's reading adds to d: d is its zero offset (mm), theta turns the next link about its axis
_WHAT_PRISMATIC = {**_WHAT, "theta_offset_rad": "turn about its axis", "d_mm": "zero offset"}
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


def describe(name: str, robot=None) -> str:
    """A parameter in words, with the name a person can type back (``--free``, ``--prior``): for a robot whose
    joints have names, ``arm_2_joint length a (arm_2_joint.a_mm)``; for the thesis's Puma its own words, ``shoulder
    offset d1 (j2.d_mm)``; else ``joint 3 length a (j3.a_mm)``.  A prismatic joint's zero offset is its d (mm)."""
    head, _, tail = name.partition(".")
    m = re.fullmatch(r"j(\d+)", head)
    if m and tail in _WHAT and (robot is None or int(m.group(1)) <= robot.n):
        j = int(m.group(1))
        what = (_WHAT_PRISMATIC if naming.is_prismatic(robot, j) else _WHAT)[tail]
        if naming.named(robot):
            return f"{naming.joint_name(robot, j)} {what} ({naming.edge_name(name, robot)})"
        if name in THESIS_NAMES and not naming.is_prismatic(robot, j):
            return f"{THESIS_NAMES[name]} ({naming.edge_name(name, robot)})"
        return f"joint {j} {what} ({naming.edge_name(name, robot)})"
    if name == "B.x_mm":
        return f"the baseline L, i.e. the overall scale ({naming.edge_name(name, robot)})"
    if head.isupper() and tail in _STATION:
        return f"station {head} {_STATION[tail]} ({naming.edge_name(name, robot)})"
    if head == "base" and tail in _BASE:
        return f"{_BASE[tail]} ({naming.edge_name(name, robot)})"
    if head == "tool" and tail in _TOOL:
        return f"{_TOOL[tail]} ({naming.edge_name(name, robot)})"
    return naming.edge_name(name, robot)


@dataclass
class Combination:
    """A direction in parameter space: ``sum coef_i * scaled parameter_i``, with its singular value ratio."""

    coefficients: dict[str, float]
    ratio: float                          # singular value / largest singular value
    because: str = ""
    #: why, when a joint that barely moves is the cause: (1-based joint, its range over the poses, rad or mm)
    because_joint: tuple[int, float] | None = None

    def reason(self, robot=None) -> str:
        """The cause in words, the joint named and its range in its own unit (mm for a prismatic joint)."""
        if self.because_joint is None:
            return self.because
        j, span = self.because_joint
        amount = f"{span:.1f} mm" if naming.is_prismatic(robot, j) else f"{np.degrees(span):.1f} deg"
        return f"{naming.joint_label(robot, j)} barely moves (range {amount} over the poses)"

    def words(self, robot=None) -> str:
        # largest first; coefficients equal to 1e-6 keep the dict's order (the held parameter first), so that rounding
        # does not swap the two names of a pair
        items = sorted(self.coefficients.items(), key=lambda kv: -round(abs(kv[1]), 6))
        big = [describe(n, robot) for n, c in items if abs(c) >= 0.25 * abs(items[0][1])][:5]
        if len(big) == 1:
            text = (f"{big[0]} has no effect on the measurements" if self.ratio <= RANK_RTOL
                    else f"{big[0]} is poorly determined")
        verb = "cannot separate" if self.ratio <= HOLD_RTOL else "can hardly separate"
        if len(big) == 2:
            text = f"{verb} {big[0]} from {big[1]}"
        elif len(big) > 2:
            text = f"{verb} " + ", ".join(big[:-1]) + f" and {big[-1]}"
        why = self.reason(robot)
        return text + (f", because {why}" if why else "")


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

    def report(self, robot=None) -> list[str]:
        """The analysis in sentences; with ``robot`` its joints are named and its units used."""
        lines = [f"{len(self.names)} parameters, rank {self.rank}, condition number {self.condition:.3g} "
                 f"(column-scaled)"]
        for c in self.unidentifiable:
            what = "not identifiable" if c.ratio <= RANK_RTOL else f"not identifiable in practice (ratio {c.ratio:.1e})"
            lines.append(f"{what}: " + c.words(robot))
        for c in self.weak:
            lines.append(f"weakly identifiable (singular value ratio {c.ratio:.1e}): " + c.words(robot))
        if self.fixed:
            lines.append("held at their design values: " + ", ".join(naming.edge_name(n, robot) for n in self.fixed))
            lines.append(f"remaining {len(self.kept)} parameters: condition number {self.kept_condition:.3g}")
        return lines


def analyse(J: np.ndarray, names: list[str],
            rejacobian: Callable[[int], np.ndarray] | None = None,
            joint_ranges_rad: np.ndarray | None = None,
            prefer_fix: Callable[[str], int] | None = None) -> Identifiability:
    """Analyse the whitened Jacobian ``J`` (m, p) of the parameters ``names``.

    ``rejacobian(k)``, when given, recomputes J with joint k's readings spread over its range; a combination that it
    makes determinable is explained as "joint k barely moves".  ``prefer_fix(name)`` ranks which parameter of a
    combination to hold (lower first); ties go to the one with the largest coefficient (:func:`_to_hold`).

    One QR of J, then every decomposition on its small R factor (:func:`small_factor`): the cost of about one SVD
    of J however many parameters are held.
    """
    m, p = J.shape
    norms = np.linalg.norm(J, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    R = small_factor(J / safe)                 # the column-scaled Jacobian's singular values and right vectors
    s, Vt = _svd(R)
    smax = s[0] if s.size and s[0] > 0 else 1.0
    ratio = np.concatenate([s / smax, np.zeros(max(0, p - s.size))])
    rank = int(np.sum(ratio > RANK_RTOL))
    cond = float(smax / s[rank - 1]) if rank == p and rank > 0 else float("inf")
    out = Identifiability(list(names), rank, cond, s)

    # automatic treatment: hold one parameter per undeterminable direction until the rest is full rank
    keep = list(range(p))
    fixed: list[int] = []
    s_k, Vt_k = s, Vt
    while keep:
        r_k = s_k / (s_k[0] if s_k.size and s_k[0] > 0 else 1.0)
        if len(s_k) == len(keep) and r_k[-1] > HOLD_RTOL:
            out.kept_condition = float(1.0 / r_k[-1])
            break
        null = _exact_null(r_k, Vt_k, len(keep))
        k = _to_hold(r_k, Vt_k, [names[i] for i in keep], prefer_fix, null)
        fixed.append(keep.pop(k))
        # the exactly undeterminable directions left once column k is held: those of the null space with no k
        # component -- no decomposition per held parameter while they last (a 19-joint tree's fit holds 14)
        while null is not None and len(null) > 1 and keep:
            null = _drop_coordinate(null, k)
            k = _to_hold(None, None, [names[i] for i in keep], prefer_fix, null)
            fixed.append(keep.pop(k))
        if keep:
            s_k, Vt_k = _svd(R[:, keep])
    out.fixed = [names[i] for i in fixed]
    out.kept = [names[i] for i in keep]

    # the undeterminable directions, written on the held parameters: each holds one, plus what absorbs it
    if fixed:
        small = np.flatnonzero(ratio <= HOLD_RTOL)
        null = Vt[small].T                                              # (p, number held)
        basis = null @ np.linalg.pinv(null[fixed, :])                   # unit on each held parameter
        for col, f in zip(basis.T, fixed):
            coef = {names[k]: float(col[k]) for k in [f, *np.flatnonzero(np.abs(col) > 0.05)]}
            v = col / np.linalg.norm(col)
            combo = Combination(coef, float(np.linalg.norm(R @ v) / smax))
            if rejacobian is not None and joint_ranges_rad is not None:
                combo.because_joint = _explain(v, combo.ratio, rejacobian, joint_ranges_rad, norms)
            out.unidentifiable.append(combo)
    # the weakest directions among the kept parameters (reported as weak below WEAK_RTOL): the hold loop's last
    # decomposition is that of the kept columns
    if keep:
        r_k = s_k / smax
        for i in np.argsort(r_k)[:3]:
            v = np.zeros(p)
            v[keep] = Vt_k[i]
            coef = {names[k]: float(v[k]) for k in np.flatnonzero(np.abs(v) > 0.05)}
            combo = Combination(coef, float(r_k[i]))
            if rejacobian is not None and joint_ranges_rad is not None:
                combo.because_joint = _explain(v, combo.ratio, rejacobian, joint_ranges_rad, norms)
            out.weakest.append(combo)
            if r_k[i] < WEAK_RTOL:
                out.weak.append(combo)
    return out


def _to_hold(ratio: np.ndarray | None, Vt: np.ndarray | None, names: list[str],
             prefer_fix: Callable[[str], int] | None, null: np.ndarray | None = None) -> int:
    """Which column to hold for the smallest direction(s) (``ratio``, ``Vt``: the kept columns' decomposition).

    A practically undeterminable direction is the last right vector; its parameters with a coefficient above 0.2 of
    the largest are candidates.  Exactly undeterminable directions (ratio <= RANK_RTOL) usually come several at once
    (base yaw with joint 1's offset, tool z with the flange d, ...), and any orthonormal basis of that null space is
    what LAPACK happens to return: the null space is taken as a whole, a parameter's weight being the length of its
    projection on it.  Then the lowest ``prefer_fix`` rank, the largest weight (equal within 1e-6 counts as equal),
    and the first in the order of ``names`` -- so the choice does not depend on rounding or on the decomposition's
    implementation.  ``null``: the null space's rows when the caller has them (:func:`_drop_coordinate`).
    """
    if null is None:
        rank = int(np.sum(ratio > RANK_RTOL))
        null = Vt[rank:] if rank < len(names) else Vt[-1:]
    weight = np.linalg.norm(null, axis=0)
    cand = [k for k in range(len(names)) if weight[k] > 0.2 * weight.max()]
    pref = {k: prefer_fix(names[k]) if prefer_fix else 0 for k in cand}
    cand = [k for k in cand if pref[k] == min(pref.values())]
    top = max(weight[k] for k in cand)
    return min(k for k in cand if weight[k] >= top * (1.0 - 1e-6))


#: the smallest kept singular value ratio for which the exact null space is followed without a decomposition per held
#: parameter (:func:`_exact_null`): far enough above RANK_RTOL that holding a column cannot push a determined
#: direction under it (a held column of weight w >= 0.2 of the largest leaves the rest >= ~0.01 of their size)
_SEPARATED = 1e4 * RANK_RTOL


def _exact_null(ratio: np.ndarray, Vt: np.ndarray, p: int) -> np.ndarray | None:
    """The exact null space's rows of ``Vt`` (orthonormal, ``(d, p)``) when there are several exactly undeterminable
    directions and every other direction is well above them (:data:`_SEPARATED`), else None.

    Why: holding a parameter w of such a null space N leaves exactly the directions of N without a w component (the
    columns left are those of the same matrix), so the next parameter to hold can be read from that subspace instead
    of a new decomposition; the choice (:func:`_to_hold`) reads only the subspace, whatever its basis."""
    rank = int(np.sum(ratio > RANK_RTOL))
    if p - rank < 2 or len(ratio) < p or rank == 0 or ratio[rank - 1] <= _SEPARATED:
        return None
    return Vt[rank:]


def _drop_coordinate(null: np.ndarray, k: int) -> np.ndarray:
    """An orthonormal basis (rows) of the vectors of the row space of ``null`` (orthonormal rows, ``(d, p)``) whose
    coordinate ``k`` is zero, without that coordinate: ``(d - 1, p - 1)``."""
    c = null[:, k]
    # a Householder reflection taking c to |c| e_1: the other rows of H null have no k component
    v = c.copy()
    v[0] += np.copysign(np.linalg.norm(c), c[0] if c[0] != 0 else 1.0)
    H = np.eye(len(c)) - 2.0 * np.outer(v, v) / (v @ v)
    return np.delete((H @ null)[1:], k, axis=1)


def small_factor(A: np.ndarray) -> np.ndarray:
    """A matrix with the singular values and right singular vectors of ``A`` (and of any subset of its columns),
    at most as many rows as columns: the R of ``A = QR`` for a tall ``A``.

    Why: the analysis decomposes the whitened Jacobian once per held parameter; one QR of the (m, p) Jacobian and
    then SVDs of the (p, p) factor cost what one SVD of the Jacobian did (``A[:, keep] = Q R[:, keep]``, Q
    orthonormal, so ``|A v| = |R v|`` for every v).
    """
    m, p = A.shape
    return np.linalg.qr(A, mode="r") if m > p else A


def _svd(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Singular values and the right singular vectors (all of them, rows of Vt, also when ``A`` is wide), each
    vector's sign fixed so that its largest-magnitude coefficient is positive: the printed combinations do not
    depend on the LAPACK routine's arbitrary signs."""
    _, s, Vt = np.linalg.svd(A, full_matrices=A.shape[0] < A.shape[1])
    big = np.argmax(np.abs(Vt), axis=1)
    return s, Vt * np.where(Vt[np.arange(len(Vt)), big] < 0, -1.0, 1.0)[:, None]


def _largest_singular(A: np.ndarray) -> float:
    """The spectral norm of a tall ``A`` from its small Gram matrix (the largest singular value is accurate there;
    only the small ones lose precision by squaring)."""
    G = A.T @ A if A.shape[0] >= A.shape[1] else A @ A.T
    return float(np.sqrt(max(np.linalg.eigvalsh(G)[-1], 0.0))) if G.size else 0.0


def _explain(v: np.ndarray, before: float, rejacobian, ranges: np.ndarray,
             norms: np.ndarray) -> tuple[int, float] | None:
    """Which joint, if spread over its range, would make the direction ``v`` (scaled parameters) far better determined.

    Checked, not guessed: the direction's response ``|J v| / |J|`` (``before`` now) is recomputed with that joint's
    readings spread over its limits; a tenfold gain names the joint.
    """
    safe = np.where(norms > 0, norms, 1.0)
    for k in np.argsort(ranges):
        if ranges[k] > np.radians(30):
            break
        J2 = rejacobian(int(k)) / safe
        s2 = _largest_singular(J2)
        if s2 > 0 and np.linalg.norm(J2 @ v) / s2 > 10 * before + 1e-6:
            return int(k) + 1, float(ranges[k])
    return None
