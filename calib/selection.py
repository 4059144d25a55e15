"""Which parameters the data determine: model selection for ``robocal identify`` (issue 24).

Why: a full geometric fit on few poses soaks noise and unmodelled motion into parameters the data cannot pin down,
and predicts new poses worse than a smaller model (FIGAROH's TIAGo study: 22 of 38 parameters at noise level, the
pruned model better on held-out poses in every split).  So identify estimates only what the data support:

1. the **full** free set is fitted (outlier decision included: the rows it rejects stay out of every later fit);
2. **significance**: a parameter whose estimate is within :data:`SIGNIFICANT` sigma of its design value is held
   there, and the fit redone, until every estimated parameter is significant.  Never held: the location (base, tool
   points, other targets and set-ups: not a property of the robot) and a parameter with a prior (a tolerance of the
   description, ``--prior``): the prior already holds it near its design value, with an uncertainty the predictions
   carry -- holding it exactly would make the predicted sigmas too small where the data do not reach;
3. **prediction**: the candidates -- the located nominal description (base and tool points only), plus the joint
   zero offsets, the significant set, the full set -- are compared by their leave-one-pose-out prediction error on the
   fit rows.  For a fixed model it comes from the fit's hat matrix (exact for a linear least-squares problem, within
   0.2 % of real refits on the TIAGo set); for the significant set the elimination itself is repeated without each
   left-out pose (:mod:`calib.pruning`), since scoring the pruned model alone would be optimistic.  The lowest wins;
   within :data:`TIE` the model with fewer parameters.  The located nominal description is a candidate, so the
   choice never predicts the left-out poses worse than the robot's own description.

Every choice sees only the rows it is given: a caller with a held-out test set passes the fit rows alone.
For each held parameter the result says why, and what more data would determine it: how many poses like these
would show its present deviation at 2 sigma, and which joint, spread over its range, would shrink its sigma most.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .accuracy import grouped_folds, locate_free, make_folds
from .covariance import from_jacobian
from .errors import RobocalError
from .identify import Identification, PointObservations, _Problem, identify
from .model import MeasurementModel
from .names import edge_name
from .pruning import SIGNIFICANT, linearise        # |estimate - design| / sigma below which a parameter is held

#: inner prediction errors within this share of the lowest are a tie, won by the model with fewer parameters
TIE = 0.02
#: up to this many poses the elimination's inner score is leave-one-out, above it 10-fold
LOO_POSES = 60
#: a pose count this many times the present one is reported as "more poses like these will not determine it"
MANY_TIMES = 20
#: held parameters listed on the terminal (all of them in the JSON)
MAX_LINES = 12


@dataclass
class Step:
    """One candidate model: its free set, its fit on the rows given and its inner prediction error."""

    name: str
    free: list[str]
    ident: Identification
    press_rms_mm: float                 # leave-one-pose-out prediction RMS (per-point 3-D distance), linearised

    def as_dict(self) -> dict:
        return {"model": self.name, "n_params": len(self.ident.free),
                "inner_cv_rms_mm": self.press_rms_mm if np.isfinite(self.press_rms_mm) else None}


@dataclass
class Held:
    """A parameter held at its design value (or prior) by the selection, why, and what would determine it."""

    name: str
    estimate: float                     # in the fit where it was last free
    sigma: float
    design: float
    reason: str
    poses_needed: int | None = None     # poses like these at which the present deviation would reach 2 sigma
    where: str = ""                     # which joint to spread, and how much sigma would shrink

    @property
    def t(self) -> float:
        return abs(self.estimate - self.design) / self.sigma if self.sigma > 0 else float("inf")

    def as_dict(self) -> dict:
        return {"name": self.name, "estimate": self.estimate, "sigma": self.sigma, "design": self.design,
                "t": self.t, "reason": self.reason, "poses_needed": self.poses_needed, "where": self.where or None}


@dataclass
class Selection:
    rule: str                           # "auto" (selection) or "all" (the full set, as asked)
    steps: list[Step]
    chosen: int
    held: list[Held] = field(default_factory=list)
    n_poses: int = 0
    inner: str = ("leave-one-pose-out prediction (linearised; the significance test repeated without each left-out "
                  "pose)")

    @property
    def ident(self) -> Identification:
        return self.steps[self.chosen].ident

    @property
    def located(self) -> Step:
        return self.steps[0]

    def as_dict(self) -> dict:
        return {"rule": self.rule, "inner_cv": self.inner, "chosen": self.steps[self.chosen].name,
                "candidates": [s.as_dict() for s in self.steps], "held": [h.as_dict() for h in self.held]}

    def lines(self, robot=None) -> list[str]:
        """The selection in words (terminal); ``robot``: parameters named by the description's joint names, angles
        in degrees under the ``_deg`` name (what ``--prior`` and ``--free`` read back)."""
        if self.rule == "all":
            return ["model selection off (--select all): every parameter of the free set is estimated"]
        cands = ", ".join(f"{s.name} {_mm(s.press_rms_mm)} ({len(s.ident.free)})" for s in self.steps)
        out = [f"model selection by {self.inner} on {self.n_poses} poses: {cands}: "
               f"chose {self.steps[self.chosen].name}"]
        for h in self.held[:MAX_LINES]:
            name, scale = _edge(h.name, robot)
            more = ""
            if h.poses_needed is not None:
                more = (f"; ~{h.poses_needed} poses like these would show a deviation this size" if
                        h.poses_needed <= MANY_TIMES * max(1, self.n_poses) else "; consistent with its design value")
            design = 0.0 if abs(h.design) < 1e-9 else h.design / scale
            out.append(f"  held {name} = {design:.6g}: {h.reason} (estimate {h.estimate / scale:.5g} ± "
                       f"{h.sigma / scale:.2g}){more}" + (f"; {h.where}" if h.where else ""))
        if len(self.held) > MAX_LINES:
            out.append(f"  ... and {len(self.held) - MAX_LINES} more held (--json: selection.held)")
        return out


def _edge(name: str, robot=None) -> tuple[str, float]:
    """A parameter's printed name (joint name, ``_deg`` for an angle) and the factor from internal units."""
    return edge_name(name, robot), (np.pi / 180.0 if name.endswith("_rad") else 1.0)


def _mm(v: float) -> str:
    return f"{v:.3f} mm" if np.isfinite(v) else "not predictable (a pose alone determines a parameter)"


# -- the inner prediction error -------------------------------------------------------------------------------------
def loo_residuals_mm(model: MeasurementModel, obs: PointObservations, ident: Identification,
                     priors: dict | None = None, groups: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) leave-one-pose-out residuals of a converged fit, linearised: ``r_(i) = (I - H_ii)^-1 r_i`` with
    ``H_ii`` the pose's 3x3 block of the hat matrix of the whitened problem (prior rows included in the normal
    matrix, so a prior keeps a parameter determined when the pose that sees it is left out); back to mm through the
    pose's whitening.  A pose whose block has an eigenvalue of one (it alone determines a direction): infinite.
    ``groups`` (N,) ints: rows of one pose (several targets) left out together, their joint block of the hat matrix
    (leaving one target out while the pose's other targets stay in the fit predicts it from the same joint readings:
    on TIAGo's four markers per pose that chose the full geometry, 7.1 mm on held-out poses against 4.5 before)."""
    prob = problem_at(model, obs, ident, priors)
    r, J = prob.residuals(ident.theta)
    kidx = [prob.names.index(n) for n in ident.free]
    Jk = J[:, kidx]
    norms = np.linalg.norm(Jk, axis=0)
    U, s, _ = np.linalg.svd(Jk / np.where(norms > 0, norms, 1.0), full_matrices=False)
    U = U[:, s > 1e-10 * (s[0] if s.size else 1.0)]
    N = obs.n
    Ui = U[: 3 * N].reshape(N, 3, -1)
    H = np.einsum("nik,njk->nij", Ui, Ui)
    A = np.eye(3)[None] - H
    ri = r[: 3 * N].reshape(N, 3)
    out = np.full((N, 3), np.inf)
    if groups is not None:
        rw = _grouped_loo(Ui, ri, groups)
        fine = np.isfinite(rw).all(axis=1)
        out[fine] = np.linalg.solve(obs._white[fine], rw[fine][..., None])[..., 0]
        return out
    ok = np.linalg.eigvalsh(0.5 * (A + A.transpose(0, 2, 1)))[:, 0] > 1e-9
    if ok.any():
        rw = np.linalg.solve(A[ok], ri[ok][..., None])[..., 0]
        out[ok] = np.linalg.solve(obs._white[ok], rw[..., None])[..., 0]
    return out


def _grouped_loo(Ui: np.ndarray, ri: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Whitened leave-one-group-out residuals (N, 3): per group of rows ``R``, ``(I - U_R U_R^T)^-1 r_R`` over its
    3|R| observations (groups of one size solved together); inf where the group alone determines a direction."""
    out = np.full(ri.shape, np.inf)
    members = [np.flatnonzero(groups == g) for g in np.unique(groups)]
    for size in sorted({len(m) for m in members}):
        R = np.array([m for m in members if len(m) == size])            # (G, size)
        U = Ui[R].reshape(len(R), 3 * size, -1)
        A = np.eye(3 * size)[None] - U @ U.transpose(0, 2, 1)
        ok = np.linalg.eigvalsh(0.5 * (A + A.transpose(0, 2, 1)))[:, 0] > 1e-9
        if ok.any():
            x = np.linalg.solve(A[ok], ri[R[ok]].reshape(int(ok.sum()), 3 * size)[..., None])[..., 0]
            out[R[ok].ravel()] = x.reshape(-1, 3)
    return out


def problem_at(model: MeasurementModel, obs: PointObservations, ident: Identification,
               priors: dict | None = None) -> _Problem:
    """The fit's problem on the rows ``obs`` with the priors on its estimated parameters, at ``ident.theta``: the
    fit's own (its last residual and Jacobian are that point's) when it ran on these rows and priors, else a new one
    (same numbers, one more evaluation of the model)."""
    pri = {n: v for n, v in (priors or {}).items() if n in ident.free}
    own = ident.problem
    if own is not None and own.obs is obs and own.priors == pri:
        return own
    return _Problem(model, obs, ident.theta[: model.P], pri)


def press_rms_mm(model, obs, ident, priors=None, groups: np.ndarray | None = None) -> float:
    """RMS of the per-point 3-D distances of :func:`loo_residuals_mm` (inf when a pose alone determines a
    parameter)."""
    e = loo_residuals_mm(model, obs, ident, priors, groups)
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))


# -- the candidates -------------------------------------------------------------------------------------------------
def offsets_free(model: MeasurementModel) -> list[str]:
    """The joint zero offsets (a prismatic joint's: its d)."""
    return [f"j{j + 1}.d_mm" if model.robot.prismatic[j] else f"j{j + 1}.theta_offset_rad"
            for j in range(model.robot.n)]


def reference_values(model: MeasurementModel, priors: dict) -> np.ndarray:
    """What a held parameter is held at: its prior's value, else the design value."""
    ref = model.nominal.copy()
    for n, (v, _) in priors.items():
        if n in model.index:
            ref[model.index[n]] = v
    return ref


@dataclass
class _Fitter:
    """The fits of one selection: the same rows, priors, loss and start for every candidate."""

    model: MeasurementModel
    obs: PointObservations
    priors: dict
    loss: str
    error_scale: str
    fit: Callable = identify
    groups: np.ndarray | None = None       # (N,) pose of each row when a pose has several rows (targets)

    def __call__(self, free: list[str], theta0: np.ndarray, start: bool = False,
                 warm: Identification | None = None) -> Identification:
        """The fit of ``free`` from ``theta0`` (held parameters stay there); ``warm``: a fit of the same free set on
        other rows (the whole set, for a cross-validation fold) where the solver starts instead."""
        pri = {n: v for n, v in self.priors.items() if n in free}
        more = {"warm": warm.theta} if warm is not None else {}
        return self.fit(self.model, self.obs, free=free, theta0=theta0, priors=pri, start=start, outliers="off",
                        loss=self.loss, error_scale=self.error_scale, **more)

    def step(self, name: str, ident: Identification, free: list[str]) -> Step:
        return Step(name, free, ident, press_rms_mm(self.model, self.obs, ident, self.priors, self.groups))

    @property
    def n_poses(self) -> int:
        return self.obs.n if self.groups is None else int(len(np.unique(self.groups)))

    def folds(self, k_max: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """Leave-one-pose-out up to :data:`LOO_POSES` poses, else ``k_max``-fold; a pose's rows together."""
        n = self.n_poses
        k = n if n <= LOO_POSES else k_max
        return make_folds(self.obs.n, k) if self.groups is None else grouped_folds(list(self.groups), k)


def select(model: MeasurementModel, obs: PointObservations, free: list[str], priors: dict | None = None,
           theta0: np.ndarray | None = None, start: bool = True, outliers: str = "flag", loss: str = "linear",
           labels: dict | None = None, rule: str = "auto", error_scale: str = "inflate",
           fit: Callable = identify, explain: bool = True,
           warm: Selection | None = None, groups=None) -> tuple[Selection, Identification]:
    """Select the model the rows ``obs`` support (see the module docstring).  Returns the selection and the first
    full fit (its outlier report names the flagged and rejected poses).  ``rule="all"``: the full set is the answer
    (the located nominal model is fitted too: it is the "before" of the accuracy).  ``explain=False`` leaves out what
    would determine each held parameter (a cross-validation fold needs only the choice).

    ``warm``: the selection on the whole set, for a cross-validation fold: each candidate's fit starts from that
    candidate's fit on the whole set (a start point only: every choice -- the identifiability guard, the outlier
    decision, the elimination, the winner -- is made again on ``obs``, and a held parameter is held at its design
    value or prior, never at a value the whole set gave it).

    ``groups``: the pose of each row (its pose id) when poses carry several targets: every inner prediction leaves a
    pose's rows out together."""
    if rule not in ("auto", "all"):
        raise RobocalError(f"--select must be auto or all, got {rule!r}")
    priors = priors or {}
    theta0 = np.array(model.nominal if theta0 is None else theta0, float)
    start_at = {s.name: s.ident for s in warm.steps} if warm is not None else {}
    more = {"warm": start_at["full set"].theta} if "full set" in start_at else {}
    full = fit(model, obs, free=free, theta0=theta0, priors=priors, start=start, outliers=outliers, loss=loss,
               labels=labels, error_scale=error_scale, **more)
    rep = full.outlier_report
    kept_obs, keep = obs, np.arange(obs.n)
    if rep is not None and rep.rejected:
        keep = np.setdiff1d(np.arange(obs.n), rep.rejected)
        kept_obs = obs.subset(keep)
    fitter = _Fitter(model, kept_obs, priors, loss, error_scale, fit, _pose_groups(groups, keep))
    loc = [n for n in locate_free(model) if n in free] or [n for n in free if n.startswith(("base.", "tool."))]
    located = fitter(loc, theta0, start=start, warm=start_at.get("located nominal"))
    steps = [fitter.step("located nominal", located, loc)]
    if rule == "all":
        steps.append(fitter.step("full set", full, list(free)))
        return Selection(rule, steps, 1, [], fitter.n_poses), full
    offs = [n for n in free if n in set(loc) | set(offsets_free(model))]
    if len(offs) > len(loc):
        steps.append(fitter.step("joint offsets", fitter(offs, located.theta, warm=start_at.get("joint offsets")),
                                 offs))
    sig, held, press = _significant(fitter, full, set(loc), reference_values(model, priors))
    if sig is not None and sig.free != full.free:
        steps.append(Step("significant", list(sig.free), sig, press))
    steps.append(fitter.step("full set", full, list(free)))
    sel = Selection(rule, steps, choose(steps), [], fitter.n_poses)
    if explain:
        sel.held = _held(fitter, sel, full, held, reference_values(model, priors))
    return sel, full


def _pose_groups(groups, keep: np.ndarray) -> np.ndarray | None:
    """The kept rows' pose labels as integers, or None when every row is its own pose."""
    if groups is None or len(groups) == 0:
        return None
    _, g = np.unique(np.asarray(groups)[keep], return_inverse=True)
    return None if g.max() + 1 == len(g) else g


def choose(steps: list[Step]) -> int:
    """The candidate with the fewest parameters among those within :data:`TIE` of the lowest inner prediction error
    (a difference that small is within the inner estimate's own noise: the simpler model is kept)."""
    press = np.array([s.press_rms_mm if np.isfinite(s.press_rms_mm) else np.inf for s in steps])
    near = np.flatnonzero(press <= (1.0 + TIE) * press.min())
    return int(min(near, key=lambda i: len(steps[i].ident.free)))


def _significant(fitter: _Fitter, full: Identification, location: set[str],
                 ref: np.ndarray) -> tuple[Identification | None, dict[str, tuple[float, float]], float]:
    """The significant set (backward elimination, :mod:`calib.pruning`) fitted, the held parameters with their
    (estimate, sigma) where they were last free, and the elimination's honest inner prediction error: the procedure
    repeated without each left-out pose (leave-one-out up to :data:`LOO_POSES` poses, else 10-fold)."""
    model, obs = fitter.model, fitter.obs
    pri = {n: v for n, v in fitter.priors.items() if n in full.free}
    lin = linearise(problem_at(model, obs, full, pri), full,
                    [ref[model.index[n]] if n in model.index else full.value(n) for n in full.free],
                    [_movable(n, location, fitter) for n in full.free], 3, obs._white)
    press = lin.cv_rms_mm(fitter.folds(10))
    free_mask, held_lin = lin.eliminate(np.arange(obs.n))
    held = {full.free[j]: v for j, v in held_lin.items()}
    if not held:
        return None, {}, press
    th = full.theta.copy()
    for n in held:
        th[full.names.index(n)] = ref[model.index[n]]
    sig = fitter([n for n, f in zip(full.free, free_mask) if f], th)
    sig, more = _eliminate(fitter, sig, location, ref)       # the nonlinear fit may leave one more under 2 sigma
    return sig, {**held, **more}, press


def _movable(name: str, location: set[str], fitter: _Fitter) -> bool:
    """May the elimination hold ``name``?  Not the location, and not a parameter with a prior: a prior already holds
    it near its design value *with its uncertainty*, which the predictions then carry; holding it exactly would
    claim a knowledge nobody has (on weak data the pruned model's predicted sigmas were 4x too small)."""
    return name not in location and name in fitter.model.index and name not in fitter.priors


def _eliminate(fitter: _Fitter, cur: Identification, location: set[str],
               ref: np.ndarray) -> tuple[Identification, dict[str, tuple[float, float]]]:
    """Backward elimination with nonlinear refits (warm start), one parameter at a time: the parameter nearest its
    reference in sigma is held there, until every estimated one lies :data:`SIGNIFICANT` sigma or more away."""
    model = fitter.model
    held: dict[str, tuple[float, float]] = {}
    for _ in range(len(cur.free)):
        worst, t_min = None, SIGNIFICANT
        for n in cur.free:
            if not _movable(n, location, fitter):
                continue
            i = cur.names.index(n)
            sd = cur.sigma[i]
            t = abs(cur.theta[i] - ref[model.index[n]]) / sd if sd > 0 else np.inf
            if t < t_min:
                worst, t_min = n, t
        if worst is None:
            break
        i = cur.names.index(worst)
        held[worst] = (float(cur.theta[i]), float(cur.sigma[i]))
        th = cur.theta.copy()
        th[i] = ref[model.index[worst]]
        cur = fitter([n for n in cur.free if n != worst], th)
    return cur, held


def _held(fitter: _Fitter, sel: Selection, full: Identification, insignificant: dict,
          ref: np.ndarray) -> list[Held]:
    """Every parameter of the full fit the chosen model does not estimate, with the reason and what would
    determine it."""
    model, chosen = fitter.model, sel.ident
    out = []
    if all(name in chosen.free or name not in model.index for name in full.free):
        return out                      # nothing held: no joint to spread for (19 Jacobians on a 19-joint tree)
    gain = _spread_gain(fitter, full)
    n = fitter.n_poses
    best = sel.steps[sel.chosen]
    for name in full.free:
        if name in chosen.free or name not in model.index:
            continue
        i = full.names.index(name)
        est, sd = insignificant.get(name, (float(full.theta[i]), float(full.sigma[i])))
        design = float(ref[model.index[name]])
        t = abs(est - design) / sd if sd > 0 else np.inf
        if name in insignificant:
            reason = f"not significant ({t:.1f} sigma from its design value)"
        else:
            reason = (f"{t:.1f} sigma from its design value, but estimating it does not improve the "
                      f"prediction of left-out poses (the {best.name} model predicts them best)")
        dev = abs(est - design)
        need = int(np.ceil(n * (SIGNIFICANT * sd / dev) ** 2)) if dev > 0 and t < SIGNIFICANT else None
        out.append(Held(name, est, sd, design, reason, need, gain.get(name, "")))
    return out


def _spread_gain(fitter: _Fitter, full: Identification) -> dict[str, str]:
    """Per estimated parameter of the full fit: the joint whose readings, spread evenly over its range (the rest of
    the poses as they are), would shrink its sigma most, when by at least a third -- "where" more poses help."""
    model, obs = fitter.model, fitter.obs
    kidx = [full.names.index(n) for n in full.free]
    pri = {n: v for n, v in fitter.priors.items() if n in full.free}

    def sigmas(q):
        o = obs.subset(np.arange(obs.n))
        o.q_rad = q
        J = _Problem(model, o, full.theta[: model.P], pri).residuals(full.theta)[1][:, kidx]
        return np.sqrt(np.clip(np.diag(from_jacobian(J, list(full.free)).matrix), 0.0, None))

    base = sigmas(obs.q_rad)
    lim = model.robot.limits_rad
    names = model.robot.description_joint_names or tuple(f"joint {j + 1}" for j in range(model.robot.n))
    best = np.ones(len(kidx))
    which = np.full(len(kidx), -1)
    for k in range(model.robot.n):
        q = obs.q_rad.copy()
        q[:, k] = np.random.default_rng(k).permutation(np.linspace(lim[k, 0], lim[k, 1], obs.n))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(base > 0, sigmas(q) / base, 1.0)
        better = ratio < best
        best[better], which[better] = ratio[better], k
    out = {}
    unit = [("mm", 1.0) if model.robot.prismatic[k] else ("deg", 180.0 / np.pi) for k in range(model.robot.n)]
    for i, n in enumerate(full.free):
        k = int(which[i])
        if k < 0 or best[i] > 2.0 / 3.0:
            continue
        u, f = unit[k]
        lo, hi = obs.q_rad[:, k].min() * f, obs.q_rad[:, k].max() * f
        out[n] = (f"poses spreading {names[k]} over its range ({lo:.0f}..{hi:.0f} of {lim[k, 0] * f:.0f}.."
                  f"{lim[k, 1] * f:.0f} {u}) would shrink its sigma {1 / best[i]:.1f}x")
    return out
