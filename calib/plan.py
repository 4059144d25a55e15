"""Design of experiments for the identification: which poses to measure, and how good a given pose set is.

Observability indices of the whitened, column-scaled identification Jacobian with singular values s_1 >= ... >= s_L
(m rows):

* O1 (Borm & Menq): (s_1 s_2 ... s_L)^(1/L) / sqrt(m) — the confidence-ellipsoid volume (D-optimality);
* O2 (Driels & Pathre): s_L / s_1 — inverse condition number;
* O3 (Nahvi, Hollerbach & Hayward): s_L — the worst-determined direction (E-optimality);
* O4 (Nahvi & Hollerbach): s_L^2 / s_1 — the noise amplification index.

Pose selection draws a pool of reachable candidate poses (inside the joint limits less a margin, away from the wrist
and elbow singularities), finds the identifiable parameter set on that pool (so the design never chases a gauge
freedom), then picks N poses greedily for the chosen index and improves the choice by exchange (Fedorov).  The
prediction that matters to the operator is printed too: the tool-position uncertainty over a test region that the
identified parameters would give, against random pose sets of the same size.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .errors import RobocalError
from .identifiability import Identifiability, analyse
from .identify import default_free, fix_preference
from .model import MeasurementModel
from .targets import TargetContext

INDICES = ("O1", "O2", "O3", "O4")
#: Chapter 6's unknowns (eq 6.6): link lengths and offsets, tool point and base position (rotations known)
CHAPTER6 = ["j2.d_mm", "j4.d_mm", "j6.d_mm", "j2.a_mm", "j3.a_mm", "tool.x_mm", "tool.y_mm", "tool.z_mm",
            "base.x_mm", "base.y_mm", "base.z_mm"]


def parameter_set(model: MeasurementModel, which: str) -> list[str]:
    """Named parameter sets: ``geometric`` (default identification set, no effects), ``full`` (with the model's
    effects), ``chapter6`` (the thesis's linear regression unknowns)."""
    sets = {"geometric": lambda: default_free(model, effects=False), "full": lambda: default_free(model, True),
            "chapter6": lambda: list(CHAPTER6)}
    if which not in sets:
        raise RobocalError(f"plan: unknown parameter set {which!r} (known: {', '.join(sets)})")
    return sets[which]()


def observability(J: np.ndarray) -> dict[str, float]:
    """O1..O4 of a (whitened, scaled) Jacobian."""
    m, L = J.shape
    s = np.linalg.svd(J, compute_uv=False)
    if s.size < L or s[-1] <= 0:
        return {"O1": 0.0, "O2": 0.0, "O3": 0.0, "O4": 0.0}
    return {"O1": float(np.exp(np.mean(np.log(s))) / np.sqrt(m)), "O2": float(s[-1] / s[0]),
            "O3": float(s[-1]), "O4": float(s[-1] ** 2 / s[0])}


class Design:
    """The Jacobian machinery for one model, parameter set and measurement noise (point observations)."""

    def __init__(self, model: MeasurementModel, names: list[str], noise_mm: float = 0.05):
        unknown = [n for n in names if n not in model.index]
        if unknown:
            raise RobocalError(f"plan: unknown parameter {unknown[0]!r}")
        if not noise_mm > 0:
            raise RobocalError(f"plan: --noise-mm must be positive, got {noise_mm}")
        self.model = model
        self.names = list(names)
        self.idx = [model.index[n] for n in names]
        self.noise_mm = noise_mm

    def rows(self, q_rad: np.ndarray) -> np.ndarray:
        """(N, 3K, p) whitened Jacobian blocks per pose: K = 1, or every tool point of a robot whose points sit on
        different links (a branched robot: each pose measures both hands)."""
        if self.model.robot.is_tree and len(self.model.robot.tool_points_mm) > 1:
            N, n = len(q_rad), self.model.robot.n
            blocks = [self.model.evaluate(q_rad, TargetContext(N, n, target=np.full(N, k)), jacobian=True).jacobian
                      for k in range(len(self.model.robot.tool_points_mm))]
            return np.concatenate(blocks, axis=1)[:, :, self.idx] / self.noise_mm
        ev = self.model.evaluate(q_rad, jacobian=True)
        return ev.jacobian[:, :, self.idx] / self.noise_mm

    def jacobian(self, q_rad: np.ndarray) -> np.ndarray:
        B = self.rows(q_rad)
        return B.reshape(-1, B.shape[-1])

    def analyse(self, q_rad: np.ndarray) -> Identifiability:
        J = self.jacobian(q_rad)
        lim = self.model.robot.limits_rad

        def rejac(k):
            q2 = q_rad.copy()
            q2[:, k] = np.linspace(lim[k, 0], lim[k, 1], len(q_rad))
            return self.jacobian(q2)

        return analyse(J, self.names, rejac, np.ptp(q_rad, axis=0), fix_preference)

    def restrict(self, names: list[str]) -> "Design":
        return Design(self.model, names, self.noise_mm)


def singular_margin(model: MeasurementModel, q_rad: np.ndarray) -> np.ndarray:
    """Smallest singular value of the 6x6 geometric Jacobian of the flange (mm-rad scaled by 500 mm): near zero at
    the elbow, wrist and shoulder singularities."""
    fp = model.kin.forward(q_rad)
    z = fp.joint_axis
    o = fp.joint_origin
    p = fp.flange_t
    Jv = np.cross(z, p[:, None, :] - o) / 500.0
    J = np.concatenate([Jv, z], axis=2).transpose(0, 2, 1)       # (N, 6, n)
    return np.linalg.svd(J, compute_uv=False)[:, -1]


def candidate_poses(model: MeasurementModel, count: int, rng: np.random.Generator, margin_deg: float = 5.0,
                    min_singular: float = 0.05, accept: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Random reachable poses (joint variables): readings drawn inside their limits less a margin, the joints they
    give inside theirs (a coupled or mimic joint follows its readings), away from singularities."""
    robot = model.robot
    lim = robot.limits_rad if robot.readings_are_joints else robot.reading_limits()
    lo, hi = lim[:, 0] + np.radians(margin_deg), lim[:, 1] - np.radians(margin_deg)
    out = []
    tries = 0
    while sum(len(o) for o in out) < count and tries < 50:
        q = lo + (hi - lo) * rng.random((count * 2, len(lo)))
        if not robot.readings_are_joints:
            q = robot.joints_from_readings(q)
        ok = singular_margin(model, q) > min_singular
        if not robot.readings_are_joints:
            ok &= robot.within_limits(q)
        if accept is not None:
            ok &= accept(q)
        out.append(q[ok])
        tries += 1
    q = np.vstack(out)[:count]
    if len(q) < count:
        raise RobocalError("plan: could not draw enough reachable poses (joint limits, singularities, visibility)")
    return q


def _score(index: str, s: np.ndarray, m: int) -> float:
    if s[-1] <= 0:
        return -np.inf
    if index == "O1":
        return float(np.sum(np.log(s)))
    if index == "O2":
        return float(s[-1] / s[0])
    if index == "O3":
        return float(s[-1])
    return float(s[-1] ** 2 / s[0])


@dataclass
class PosePlan:
    q_rad: np.ndarray
    names: list[str]
    index: str
    indices: dict[str, float]
    identifiability: Identifiability
    predicted_sigma_mm: dict[str, float]                     # over the test region: rms, max
    random_sigma_mm: dict[str, float]                        # the same for random poses of the same count
    random_indices: dict[str, float] = field(default_factory=dict)


def position_sigma(design: Design, q_plan: np.ndarray, q_test: np.ndarray) -> np.ndarray:
    """1-sigma tool-position uncertainty (mm, RMS over x, y, z) at test poses from the parameters identified on the
    plan (first-order: J_test C J_test^T, C = (J^T J)^-1 with the whitened plan Jacobian)."""
    J = design.jacobian(q_plan)
    C = np.linalg.pinv(J.T @ J)
    B = design.rows(q_test) * design.noise_mm                     # un-whiten: mm per parameter
    var = np.einsum("nip,pq,niq->ni", B, C, B)
    return np.sqrt(np.mean(var, axis=1))


def select_poses(model: MeasurementModel, count: int, names: list[str] | None = None, index: str = "O1",
                 noise_mm: float = 0.05, seed: int = 0, pool: int = 2000, test: int = 500,
                 progress: Callable[[str, float], None] | None = None,
                 accept: Callable[[np.ndarray], np.ndarray] | None = None, compare: bool = True) -> PosePlan:
    """Choose ``count`` poses maximising an observability index (see the module docstring).

    ``compare=False`` skips what only a report needs -- the predicted uncertainty on ``test`` poses and the same
    for random pose sets (``predicted_sigma_mm``, ``random_*`` left empty) -- for callers that want the poses only;
    the poses are the same either way (those draws come after the choice)."""
    if index not in INDICES:
        raise RobocalError(f"plan: unknown index {index!r} (known: {', '.join(INDICES)})")
    names = names or parameter_set(model, "geometric")
    rng = np.random.default_rng(seed)
    cand = candidate_poses(model, pool, rng, accept=accept)
    design = Design(model, names, noise_mm)
    ident = design.analyse(cand)
    design = design.restrict(ident.kept)
    p = len(design.names)
    B = design.rows(cand)                                        # (M, 3K, p)
    per = B.shape[1]
    if per * count < p:
        raise RobocalError(f"plan: {count} poses give {per * count} observations for {p} identifiable parameters; "
                           f"ask for at least {int(np.ceil(p / per))} poses")
    col = np.linalg.norm(B.reshape(-1, p), axis=0) / np.sqrt(len(cand))
    Bs = B / col                                                 # scaled parameters: comparable columns
    chosen: list[int] = []
    ridge = 1e-6 * np.eye(p)
    A = ridge.copy()
    # greedy: D-optimal increment det(I + B_c A^-1 B_c^T) for O1; for the others, the index itself on a subsample
    for k in range(count):
        Ainv = np.linalg.inv(A)
        avail = np.setdiff1d(np.arange(len(cand)), chosen)
        if index == "O1" or k < p // 3 + 1:
            Ba = Bs[avail]
            S = (Ba @ Ainv) @ Ba.transpose(0, 2, 1)             # B_c A^-1 B_c^T, as two products
            gain = np.linalg.slogdet(np.eye(per) + S)[1]
        else:
            sub = rng.choice(avail, size=min(200, len(avail)), replace=False)
            gain = np.full(len(avail), -np.inf)
            pos = {c: i for i, c in enumerate(avail)}
            for c in sub:
                s = np.sqrt(np.clip(np.linalg.eigvalsh(A + Bs[c].T @ Bs[c])[::-1], 0, None))
                gain[pos[c]] = _score(index, s, per * (k + 1))
        best = int(avail[int(np.argmax(gain))])
        chosen.append(best)
        A = A + Bs[best].T @ Bs[best]
        if progress:
            progress("choosing poses", (k + 1) / count)
    # exchange pass: swap a chosen pose for a candidate when the index improves
    def indices_of(sels: np.ndarray, i: int) -> list[float]:
        """The index of each selection (T, count), which differ from ``chosen`` in pose ``i`` only.  O1 (the sum of
        the log singular values) is half the log-determinant of the normal matrix, which a swap changes by two
        rank-3 terms: T small determinants instead of T SVDs.  The others need the singular values: one batched
        SVD."""
        if index == "O1":
            Bc = Bs[chosen].reshape(-1, p)                     # one BLAS product (einsum's loop was 10x slower)
            G = Bc.T @ Bc - Bs[chosen[i]].T @ Bs[chosen[i]]
            Bt = Bs[sels[:, i]]
            sign, logdet = np.linalg.slogdet(G + Bt.transpose(0, 2, 1) @ Bt)
            return [0.5 * float(ld) if sg > 0 else -np.inf for sg, ld in zip(sign, logdet)]
        s = np.linalg.svd(Bs[sels].reshape(len(sels), -1, p), compute_uv=False)
        return [_score(index, si, per * sels.shape[1]) for si in s]

    current = indices_of(np.array([chosen]), 0)[0]
    for sweep in range(2):
        improved = False
        for i in range(len(chosen)):
            trial = rng.choice(np.setdiff1d(np.arange(len(cand)), chosen), size=min(40, len(cand) - count),
                               replace=False)
            sels = np.repeat(np.array([chosen]), len(trial), axis=0)
            sels[:, i] = trial
            for c, v in zip(trial, indices_of(sels, i)):  # each trial swaps only pose i: judged one after another
                if v > current + 1e-12:
                    chosen, current, improved = chosen[:i] + [int(c)] + chosen[i + 1:], v, True
            if progress:
                progress("exchanging", (sweep * len(chosen) + i + 1) / (2 * len(chosen)))
        if not improved:
            break
    q_plan = cand[chosen]
    if not compare:
        return PosePlan(q_plan, design.names, index, observability(design.jacobian(q_plan) / col), ident, {}, {})
    q_test = candidate_poses(model, test, rng, accept=accept)
    sig = position_sigma(design, q_plan, q_test)
    rand = []
    rand_idx = []
    for _ in range(5):
        q_r = candidate_poses(model, count, rng, accept=accept)
        rand.append(position_sigma(design, q_r, q_test))
        rand_idx.append(observability(design.jacobian(q_r) / col))
    rs = np.stack(rand)
    return PosePlan(q_plan, design.names, index, observability(design.jacobian(q_plan) / col), ident,
                    {"rms": float(np.sqrt(np.mean(sig ** 2))), "max": float(sig.max())},
                    {"rms": float(np.sqrt(np.mean(rs ** 2))), "max": float(np.median(rs.max(axis=1)))},
                    {k: float(np.median([d[k] for d in rand_idx])) for k in INDICES})
