"""Whole-robot identification (Chapter 6 and its future work) with the one forward model.

Observations are either tool-target positions with their covariances (:class:`PointObservations`) or the raw
theodolite readings with their angular noise (:class:`AngleObservations`, station parameters estimated alongside).

The pipeline:

1. **start** — the robot base in the measurement frame by a rigid fit (Kabsch) of the nominal tool points to the
   measured ones, then Chapter 6's linear regression (eq 6.6): with the rotations fixed the tool point is *linear* in
   every translation of the chain (link lengths a, offsets d, base position, tool point), so one linear solve gives them;
2. **identifiability** — the whitened Jacobian of the free parameters is analysed (:mod:`calib.identifiability`);
   undeterminable combinations are fixed automatically and reported in words;
3. **nonlinear least squares** — trust-region reflective with the model's analytic Jacobian; a first fit with a
   robust loss shows the poses whose whitened residual is implausible (chi-square, 99.99 %): they are flagged, and
   left out only in ``reject`` mode when they do not cluster in a pose condition (:mod:`calib.outliers`); the final
   fit uses plain least squares or the loss asked for (Huber, Cauchy);
4. **uncertainty** — covariance ``(J^T W J)^-1`` of the kept parameters (inflated by the reduced chi-square when that
   exceeds 1), standard deviations and correlations, with |rho| > 0.9 flagged.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from calib.effects.drivers import undriven

from .angles import rigid_fit, rpy_from_matrix, wrap_angle
from .effects import PoseContext
from .errors import RobocalError
from .identifiability import Identifiability, analyse
from .model import MeasurementModel
from .outliers import OutlierReport, check_mode, decide, pose_conditions
from .covariance import correlation, from_jacobian, involved
from .names import effect_label, prose
from .theodolite import Station


@dataclass
class PointObservations:
    """Measured tool-target positions (measurement frame) for joint readings."""

    q_rad: np.ndarray                     # (N, n)
    points_mm: np.ndarray                 # (N, 3)
    cov_mm2: np.ndarray | None = None     # (N, 3, 3); default sigma_mm isotropic
    sigma_mm: float = 0.05
    ctx: PoseContext | None = None
    #: the rows' whitening when the caller has it already (W with W^T W = cov^-1, as computed below): a diagnosis
    #: builds observations of its rows for every fold fit, and the per-row inverse and Cholesky cost more than the fit
    #: of a small fold
    white: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        self.q_rad = np.atleast_2d(np.asarray(self.q_rad, float))
        self.points_mm = np.atleast_2d(np.asarray(self.points_mm, float))
        N = len(self.q_rad)
        if self.points_mm.shape != (N, 3):
            raise RobocalError(f"identification: {N} poses but {len(self.points_mm)} measured points")
        for what, arr in (("joint readings", self.q_rad), ("points", self.points_mm)):
            bad = ~np.isfinite(arr).all(axis=1)
            if bad.any():
                raise RobocalError(f"identification: pose {int(np.flatnonzero(bad)[0]) + 1} has a non-finite "
                                   f"value in its {what}")
        if self.cov_mm2 is None:
            self.cov_mm2 = np.broadcast_to(np.eye(3) * self.sigma_mm ** 2, (N, 3, 3)).copy()
        # whitening: W = L L^T with L from the inverse covariance
        self._white = whitening(self.cov_mm2) if self.white is None else self.white

    @property
    def n(self) -> int:
        return len(self.q_rad)

    def subset(self, idx) -> "PointObservations":
        return PointObservations(self.q_rad[idx], self.points_mm[idx], self.cov_mm2[idx], self.sigma_mm,
                                 self.ctx.subset(idx) if self.ctx is not None else None, white=self._white[idx])


def whitening(cov_mm2: np.ndarray) -> np.ndarray:
    """(N, 3, 3) W with W^T W = cov^-1 per row (whitened residual = W r): row by row, so a subset's whitening is
    the same rows of the whole set's."""
    return np.linalg.cholesky(np.linalg.inv(cov_mm2)).transpose(0, 2, 1)


@dataclass
class AngleObservations:
    """Raw theodolite readings (N, 2k) ordered (Hz_1, V_1, Hz_2, V_2, ...) of the tool target."""

    q_rad: np.ndarray
    readings_rad: np.ndarray
    stations: list[Station]
    faces: list[int] | None = None
    ctx: PoseContext | None = None
    free_station_params: list[str] = field(default_factory=lambda: ["B.x_mm", "B.z_mm", "A.yaw_rad", "B.yaw_rad"])

    def __post_init__(self):
        self.q_rad = np.atleast_2d(np.asarray(self.q_rad, float))
        self.readings_rad = np.atleast_2d(np.asarray(self.readings_rad, float))
        if self.readings_rad.shape != (len(self.q_rad), 2 * len(self.stations)):
            raise RobocalError(f"identification: expected {2 * len(self.stations)} readings per pose for "
                               f"{len(self.stations)} stations, got {self.readings_rad.shape[1]}")
        if not np.isfinite(self.readings_rad).all() or not np.isfinite(self.q_rad).all():
            raise RobocalError("identification: a reading or joint angle is not finite")
        names = {s.name for s in self.stations}
        for p in self.free_station_params:
            st, _, par = p.partition(".")
            if st not in names or par not in Station.PARAMS:
                raise RobocalError(f"identification: unknown station parameter {p!r} "
                                   f"(stations {sorted(names)}, parameters {', '.join(Station.PARAMS)})")
        self.faces = self.faces or [1] * len(self.stations)

    @property
    def n(self) -> int:
        return len(self.q_rad)

    def subset(self, idx) -> "AngleObservations":
        return AngleObservations(self.q_rad[idx], self.readings_rad[idx], self.stations, self.faces,
                                 self.ctx.subset(idx) if self.ctx is not None else None,
                                 list(self.free_station_params))


@dataclass
class Identification:
    names: list[str]                  # every parameter (model + station)
    theta: np.ndarray                 # estimate (fixed ones at their values)
    free: list[str]                   # estimated
    fixed: list[str]                  # held (by request or by the identifiability guard)
    cov: np.ndarray                   # (P, P), zero rows/columns for fixed parameters
    identifiability: Identifiability
    residual_rms: float               # RMS of the unweighted residuals (mm or rad)
    reduced_chi2: float
    outliers: list[int]               # 0-based pose indices flagged as gross errors
    n_obs: int
    stations: list[Station] | None = None
    outlier_report: OutlierReport | None = None    # flagged, rejected, cluster (calib.outliers)
    #: directions of the kept parameters the data do not determine (calib.covariance): named, not given a sigma
    undetermined: list = field(default_factory=list)
    #: how the covariance is scaled: "inflate" (by the reduced chi-square when above 1) or "residual" (by it always:
    #: no noise was given, the errors come from the fit's own scatter)
    error_scale: str = "inflate"
    #: the final fit's problem, its last evaluation (residual and Jacobian at ``theta``) kept: what scores the fit
    #: afterwards on the same rows and priors (the selection's leave-one-out, its linearisation) reuses it
    problem: object = field(default=None, repr=False, compare=False)

    @property
    def sigma(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    def value(self, name: str) -> float:
        return float(self.theta[self.names.index(name)])

    def std(self, name: str) -> float:
        return float(self.sigma[self.names.index(name)])

    def correlation_matrix(self) -> np.ndarray:
        """Correlations of the estimated parameters (order of ``free``), within [-1, 1] (:mod:`calib.covariance`)."""
        idx = [self.names.index(n) for n in self.free]
        return correlation(self.cov[np.ix_(idx, idx)])

    def undetermined_names(self) -> set[str]:
        """Estimated parameters carrying a direction the data do not determine (their sigma means nothing)."""
        return involved(self.undetermined)

    def correlations(self, threshold: float = 0.9) -> list[tuple[str, str, float]]:
        R = self.correlation_matrix()
        out = []
        for a in range(len(self.free)):
            for b in range(a + 1, len(self.free)):
                if abs(R[a, b]) > threshold:
                    out.append((self.free[a], self.free[b], float(R[a, b])))
        return out


def default_free(model: MeasurementModel, effects: bool = True) -> list[str]:
    """The conventional parameter set: base, per link theta offset, a, alpha and d (beta instead of d for links
    joining parallel axes), tool point; plus every effect parameter except the two-slope shape parameters."""
    r = model.robot
    free = [n for n in model.kin.names if n.startswith(("base.", "tool."))]
    for j in range(r.n):
        free += [f"j{j + 1}.theta_offset_rad", f"j{j + 1}.a_mm", f"j{j + 1}.alpha_rad"]
        free.append(f"j{j + 1}.beta_rad" if r.hayati[j] else f"j{j + 1}.d_mm")
    if effects:
        for e in model.effects:
            for q in e.qualified_names():
                if q.endswith(("compliance2_rad_per_nm", "breakpoint_nm")):
                    continue
                free.append(q)
    order = {n: i for i, n in enumerate(model.names)}
    return sorted(free, key=order.get)


def fix_preference(name: str) -> int:
    """Which parameter of an undeterminable combination to hold (lower first): station parameters first (the ruler
    pre-calibration measures them), then design values, then the nuisances (tool, base)."""
    if name[:2] in ("A.", "B.") or name.split(".")[0].isupper():
        return 0
    if name.endswith(".beta_rad") or name.endswith(".d_mm") and name.startswith("j"):
        return 1
    if name.startswith("j"):
        return 2
    if name.startswith(("tool.",)):
        return 4
    if name.startswith("base."):
        return 5
    return 3


# -- the residual function ------------------------------------------------------------------------------------
class _Problem:
    def __init__(self, model: MeasurementModel, obs, theta0: np.ndarray, priors: dict[str, tuple[float, float]]):
        self.model = model
        self.obs = obs
        self.angles = isinstance(obs, AngleObservations)
        self.names = list(model.names)
        self.theta0 = np.array(theta0, float)
        if self.angles:
            self.station_names = [f"{s.name}.{p}" for s in obs.stations for p in Station.PARAMS]
            self.names += self.station_names
            self.theta0 = np.concatenate([self.theta0] + [s.params() for s in obs.stations])
        self.priors = priors
        for n in priors:
            if n not in self.names:
                raise RobocalError(f"identification: prior on unknown parameter {n!r}")
        self.ctx = obs.ctx

    def stations(self, theta):
        if not self.angles:
            return None
        P = self.model.P
        k = len(Station.PARAMS)
        return [s.with_params(theta[P + i * k:P + (i + 1) * k]) for i, s in enumerate(self.obs.stations)]

    def residuals(self, theta, jac: bool = True):
        """Whitened residuals (m,) and their Jacobian (m, P_total) w.r.t. all parameters.

        The last evaluation is kept: the solver asks for the residuals at a point and then, when it accepts the step,
        for the Jacobian at the same point, which is completed from that evaluation's forward pass
        (:meth:`calib.model.MeasurementModel.complete_jacobian`) instead of a second one; the identifiability
        analysis, the solver's first step and the covariance at its last point ask for the same Jacobian (read-only)."""
        theta = np.asarray(theta, float)
        last = getattr(self, "_last", None)
        if last is None or last[0].shape != theta.shape or not np.array_equal(last[0], theta):
            r, ev = self._evaluate(theta)
            last = self._last = [theta.copy(), r, ev, None]
        if jac and last[3] is None:
            J = self._jacobian(theta, last[2])
            J.flags.writeable = False
            last[3] = J
        return last[1].copy(), (last[3] if jac else None)

    def last_points(self, theta) -> np.ndarray:
        """The model's points (N, 3) at ``theta``: the kept evaluation's when it was at ``theta`` (the same call)."""
        theta = np.asarray(theta, float)
        last = getattr(self, "_last", None)
        if last is not None and last[0].shape == theta.shape and np.array_equal(last[0], theta):
            return last[2].point_mm
        return self.model.points(self.obs.q_rad, self.ctx, theta[: self.model.P])

    def _evaluate(self, theta):
        ev = self.model.evaluate(self.obs.q_rad, self.ctx, theta[: self.model.P])
        return self._residual(theta, ev), ev

    def seed(self, theta: np.ndarray, ev, J: np.ndarray) -> None:
        """Keep ``ev`` and ``J`` as the evaluation at ``theta`` (another problem's, with the same model, joint
        readings, context, whitening and priors: :class:`SharedStart`); the residuals are this problem's, from the
        model's points there, by the same arithmetic as :meth:`residuals`."""
        theta = np.asarray(theta, float)
        self._last = [theta.copy(), self._residual(theta, ev), ev, J]

    def _residual(self, theta, ev) -> np.ndarray:
        """Whitened residuals (and the priors') at ``theta`` from the model's evaluation ``ev`` there."""
        if not self.angles:
            r = np.einsum("nij,nj->ni", self.obs._white, self.obs.points_mm - ev.point_mm).ravel()
        else:
            st = self.stations(theta)
            d = self.obs.readings_rad - self.model.readings_of(ev, st, self.obs.faces)
            d[:, 0::2] = wrap_angle(d[:, 0::2])
            r = (d / self._sigmas(st)).ravel()
        if self.priors:
            r = np.concatenate([r, [(val - theta[self.names.index(n)]) / sd for n, (val, sd) in self.priors.items()]])
        return r

    @staticmethod
    def _sigmas(st):
        return np.concatenate([[s.sigma_hz_rad, s.sigma_v_rad] for s in st])

    def _jacobian(self, theta, ev):
        P = self.model.P
        self.model.complete_jacobian(ev)
        if not self.angles:
            J = -np.matmul(self.obs._white, ev.jacobian).reshape(-1, P)
        else:
            st = self.stations(theta)
            sig = self._sigmas(st)
            _, Jm = self.model.readings_of(ev, st, self.obs.faces, jacobian=True)
            Js = self._station_jacobian(st, ev.point_mm)
            J = -np.concatenate([Jm, Js], axis=2) / sig[None, :, None]
            J = J.reshape(-1, len(self.names))
        if self.priors:
            Jp = np.zeros((len(self.priors), len(self.names)))
            for k, (n, (_, sd)) in enumerate(self.priors.items()):
                Jp[k, self.names.index(n)] = -1.0 / sd
            J = np.vstack([J, Jp])
        return J

    def _station_jacobian(self, st, points_mm):
        """d readings / d station parameters by central differences (a few cheap observe calls, no kinematics)."""
        k = len(Station.PARAMS)
        N = self.obs.n
        J = np.zeros((N, 2 * len(st), len(st) * k))
        for si, s in enumerate(st):
            base = s.params()
            for pi in range(k):
                h = 1e-3 if Station.PARAMS[pi].endswith("_mm") else 1e-7
                vals = []
                for sign in (1, -1):
                    p = base.copy()
                    p[pi] += sign * h
                    hz, v = s.with_params(p).observe(points_mm, self.obs.faces[si])
                    vals.append((hz, v))
                dh = wrap_angle(vals[0][0] - vals[1][0]) / (2 * h)
                dv = (vals[0][1] - vals[1][1]) / (2 * h)
                J[:, 2 * si, si * k + pi] = dh
                J[:, 2 * si + 1, si * k + pi] = dv
        return J


def check_drivers(model: MeasurementModel, obs, where: str) -> None:
    """An effect whose driver does not vary over the poses (no time, temperature, approach direction or load) would
    be a column of zeros, held silently by the guard, or (a constant condition: one temperature) a constant the
    geometry absorbs, estimated from noise: one line instead, naming the effect and the condition that does not vary
    (the same words the diagnosis gives under "not tested": :func:`calib.effects.drivers.undriven`)."""
    bodies = any(e.adds_bodies for e in model.effects)       # identified masses load what the description lacks
    for e in model.effects:
        why = None if bodies and e.driven_by == "load" else undriven(e, obs.q_rad, obs.ctx, model.robot)
        if why:
            raise RobocalError(f"{where}: effect {effect_label(model.robot, e)}: nothing drives it in these data: "
                               f"{prose(why, model.robot)}")
    theta = model.nominal.copy()
    for k in ("x_mm", "y_mm", "z_mm"):        # a tool point off every axis: the geometry must not hide the effect
        if f"tool.{k}" in model.index:
            theta[model.index[f"tool.{k}"]] += 100.0
    ev = model.evaluate(obs.q_rad, obs.ctx, theta, jacobian=True)
    for e, s in zip(model.effects, model.effect_slices):
        if bodies and (e.driven_by == "load" or e.adds_bodies):
            continue              # seen through each other, from zero: calib.effects.mass_moment.check_scale
        if not np.any(np.abs(ev.jacobian[:, :, s]) > 1e-12):
            raise RobocalError(f"{where}: effect {effect_label(model.robot, e)}: nothing drives it in these data (the "
                               f"condition it "
                               f"follows -- time, temperature, approach direction or load -- does not vary over the "
                               f"poses)")


def initial_base(model: MeasurementModel, q_rad, points_mm, ctx=None, theta=None) -> np.ndarray:
    """Base pose (parameters of the base) by a rigid fit of nominal tool points (robot frame) to measured ones."""
    th = np.array(model.nominal if theta is None else theta, float)
    idx = [model.index[f"base.{k}"] for k in ("x_mm", "y_mm", "z_mm", "yaw_rad", "pitch_rad", "roll_rad")]
    th[idx] = 0.0
    p_robot = model.points(q_rad, ctx, th)
    R, t = rigid_fit(p_robot, points_mm)
    roll, pitch, yaw = rpy_from_matrix(R)
    th[idx] = [*t, yaw, pitch, roll]
    return th


def linear_translations(model: MeasurementModel, obs: PointObservations, theta: np.ndarray,
                        names: list[str]) -> np.ndarray:
    """Chapter 6, eq 6.6: with rotations fixed the tool point is linear in the chain's translations; solve them."""
    th = theta.copy()
    idx = [model.index[n] for n in names]
    for n in names:
        if not n.endswith("_mm"):
            raise RobocalError(f"linear regression (eq 6.6): {n} is not a translation")
    ev = model.evaluate(obs.q_rad, obs.ctx, th, jacobian=True)
    A = ev.jacobian[:, :, idx]                                  # exact coefficients A_k, B_k, C_k of eq 6.6
    rest = ev.point_mm - np.einsum("nip,p->ni", A, th[idx])
    Aw = np.einsum("nij,njp->nip", obs._white, A).reshape(-1, len(idx))
    bw = np.einsum("nij,nj->ni", obs._white, obs.points_mm - rest).ravel()
    sol, *_ = np.linalg.lstsq(Aw, bw, rcond=None)
    th[idx] = sol
    return th


class SharedStart:
    """The start of several fits that differ only in their measured points: pass one to each
    :func:`identify` call (``shared=``); the first fills it, the others reuse it.

    Why: a re-solve from a converged fit with the points moved (the pose set's stations' term,
    :func:`offline.reduction.pose_errors.station_variance`) starts every time from the same parameters with the same
    joint readings, so the model's evaluation there -- its points and Jacobian, and so the whitened residuals'
    Jacobian, which does not depend on the measured points -- and the identifiability analysis of that Jacobian are
    the same floats each time; only the residuals change, and they are computed from the kept evaluation by the very
    arithmetic of a fresh one.  A fit that does not start from the same place (another model, joint readings,
    context, whitening, priors, free set or start parameters; a linear start, which depends on the points; angle
    observations) neither uses nor fills it: the result never depends on whether one is passed."""

    def __init__(self) -> None:
        self._kept: _Kept | None = None

    def analysis(self, prob: "_Problem", theta: np.ndarray, free: list[str], explain: bool,
                 run: Callable[[], Identifiability]) -> Identifiability:
        """``run()`` (the analysis of the problem's Jacobian at ``theta``), or the kept analysis with the kept
        evaluation seeded into ``prob`` (:meth:`_Problem.seed`) when the start is the same."""
        k = self._kept
        if k is not None and k.same(prob, theta, free, explain):
            prob.seed(k.theta, k.ev, k.jacobian)
            return k.analysis
        ident = run()
        if k is None:
            th, _, ev, J = prob._last
            self._kept = _Kept(prob.model, prob.obs.q_rad.copy(), prob.obs._white.copy(), prob.ctx,
                               list(prob.priors.items()), list(free), explain, th, ev, J, ident)
        return ident


@dataclass
class _Kept:
    """A :class:`SharedStart`'s first fit: what its start depends on, its evaluation there and its analysis."""

    model: MeasurementModel
    q_rad: np.ndarray
    white: np.ndarray
    ctx: PoseContext | None
    priors: list
    free: list[str]
    explain: bool
    theta: np.ndarray
    ev: object
    jacobian: np.ndarray
    analysis: Identifiability

    def same(self, prob: "_Problem", theta: np.ndarray, free: list[str], explain: bool) -> bool:
        return (self.model is prob.model and self.ctx is prob.ctx and self.explain == explain
                and self.free == list(free) and self.priors == list(prob.priors.items())
                and np.array_equal(self.theta, theta) and np.array_equal(self.q_rad, prob.obs.q_rad)
                and np.array_equal(self.white, prob.obs._white))


@dataclass
class _Setup:
    """What the steps of :func:`identify` share: the problem, the free and kept sets, the start point."""

    prob: _Problem
    free: list[str]
    per: int                       # observations per pose
    theta: np.ndarray | None = None
    ident: Identifiability | None = None

    @property
    def m_obs(self) -> int:
        return self.prob.obs.n * self.per


def _free_set(model: MeasurementModel, prob: _Problem, obs, free: list[str] | None) -> list[str]:
    if free is None:
        free = default_free(model)
        if prob.angles:
            free = free + list(obs.free_station_params)
    unknown = [n for n in free if n not in prob.names]
    if unknown:
        raise RobocalError(f"identification: unknown parameter {unknown[0]!r} in the free set")
    return free


def _check_enough_poses(model: MeasurementModel, st: _Setup, priors: dict) -> None:
    """Too few observations for the request?  Count what a rich experiment could identify (random poses)."""
    if st.m_obs >= len(st.free):
        return
    obs = st.prob.obs
    lim = model.robot.limits_rad
    rng = np.random.default_rng(0)
    rich_q = lim[:, 0] + (lim[:, 1] - lim[:, 0]) * rng.random((max(40, len(st.free)), model.robot.n))
    rich = obs.subset(np.zeros(len(rich_q), int))
    rich.q_rad = rich_q
    free_idx = [st.prob.names.index(n) for n in st.free]
    Jr = _Problem(model, rich, st.prob.theta0, priors).residuals(st.prob.theta0)[1][:, free_idx]
    k = analyse(Jr, st.free).kept
    if st.m_obs + len(priors) < len(k):
        raise RobocalError(f"identification: {st.m_obs} observations from {obs.n} poses for {len(k)} identifiable "
                           f"parameters; measure at least {int(np.ceil(len(k) / st.per))} poses")


def _identifiability(model: MeasurementModel, st: _Setup, priors: dict, start: bool,
                     warm: np.ndarray | None = None, explain: bool = True, shared: SharedStart | None = None) -> None:
    """Step 2 (and Chapter 6's linear step for the start): which free parameters the data determine.  ``warm``: the
    free parameters start there (the analysis too); a parameter the analysis holds goes back to its start value.
    ``explain``: look for the joint whose wider range would determine a held or weak direction (a Jacobian per joint
    that barely moves: only for a fit whose analysis is reported; the held set does not depend on it)."""
    prob, obs = st.prob, st.prob.obs
    theta = prob.theta0.copy()
    free_idx = [prob.names.index(n) for n in st.free]
    if warm is not None:
        theta[free_idx] = np.asarray(warm, float)[free_idx]
    ranges = np.ptp(obs.q_rad, axis=0)

    def rejac(k):
        o2 = obs.subset(np.arange(obs.n))
        lo, hi = model.robot.limits_rad[k]
        o2.q_rad = o2.q_rad.copy()
        o2.q_rad[:, k] = np.linspace(lo, hi, obs.n)
        return _Problem(model, o2, theta, priors).residuals(theta)[1][:, free_idx]

    def run():
        return analyse(prob.residuals(theta)[1][:, free_idx], st.free, rejac if explain else None, ranges,
                       fix_preference)

    if shared is not None and not start and not prob.angles:
        ident = shared.analysis(prob, theta, st.free, explain, run)
    else:
        ident = run()
    if start and not prob.angles:
        # Chapter 6's linear step for the translations that stay free (held ones keep their design values), then
        # the analysis again at this better point: a null tool on the flange axis hides the wrist, for example
        for _ in range(2):
            trans = [n for n in ident.kept if n.endswith("_mm") and n in model.kin.index]
            theta[: model.P] = linear_translations(model, obs, prob.theta0[: model.P], trans)
            ident = run()
            if all(n in trans for n in ident.kept if n.endswith("_mm") and n in model.kin.index):
                break
    held = [prob.names.index(n) for n in ident.fixed]
    theta[held] = prob.theta0[held]
    if len(ident.kept) > st.m_obs + len(priors):
        raise RobocalError(f"identification: {st.m_obs} observations for {len(ident.kept)} identifiable parameters; "
                           f"measure at least {int(np.ceil(len(ident.kept) / st.per))} poses")
    st.theta, st.ident = theta, ident


def _solve(problem: _Problem, theta_full: np.ndarray, kidx: np.ndarray, loss: str, max_nfev: int) -> np.ndarray:
    """Step 3: least squares over the kept parameters (the rest held in ``theta_full``): Gauss-Newton
    (:func:`_gauss_newton`) for the plain and the soft L1 loss when its full steps keep lowering the cost, else
    scipy's trust region from the same start."""
    if loss in _GN_LOSSES:
        # a robust fit starts from the plain fit's minimum (the usual start of reweighted least squares)
        start = theta_full if loss == "linear" else _gauss_newton(problem, theta_full, kidx, max_nfev)
        done = None if start is None else _gauss_newton(problem, start, kidx, max_nfev, loss=loss)
        if done is not None:
            return done
    from scipy import optimize      # 0.3-0.5 s to import: only the commands that fit pay it (not plan, compensate)

    def fun(x):
        th = theta_full.copy()
        th[kidx] = x
        return problem.residuals(th, jac=False)[0]

    def jac(x):
        th = theta_full.copy()
        th[kidx] = x
        return problem.residuals(th)[1][:, kidx]

    res = optimize.least_squares(fun, theta_full[kidx], jac=jac, method="trf", x_scale="jac", loss=loss,
                                 f_scale=_F_SCALE, max_nfev=max_nfev)
    out = theta_full.copy()
    out[kidx] = res.x
    return out


#: the losses :func:`_gauss_newton` minimises itself (scipy's ``least_squares`` with ``f_scale`` :data:`_F_SCALE`
#: for the rest, and as the fallback)
_GN_LOSSES = ("linear", "soft_l1")
_F_SCALE = 3.0


def _robust_weights(r: np.ndarray, loss: str) -> tuple[float, np.ndarray, np.ndarray]:
    """``(cost, r', w')``: the cost (twice scipy's ``least_squares`` cost: the sum of squares for ``linear``) and the
    residuals and Jacobian rows scaled by ``w' = sqrt(rho')`` for the next step.  ``soft_l1`` (``f_scale``
    :data:`_F_SCALE`): iteratively reweighted least squares -- rho(z) = 2 (sqrt(1 + z) - 1) is concave in z = (r /
    f_scale)^2, so the weighted sum of squares with the weights rho' at the current point bounds the cost from
    above, and a step lowering it lowers the cost; the fixed point is where scipy's trust region ends (the same
    gradient, J^T rho' r = 0).  Not scipy's own second-order scaling: its full steps overshoot from a start with
    gross errors."""
    if loss == "linear":
        return float(r @ r), r, np.ones_like(r)
    s = np.sqrt(1.0 + (r / _F_SCALE) ** 2)
    w = 1.0 / np.sqrt(s)                        # sqrt(rho') = (1 + z)^-1/4
    return float(_F_SCALE ** 2 * np.sum(2.0 * (s - 1.0))), r * w, w


def _gauss_newton(problem: _Problem, theta_full: np.ndarray, kidx: np.ndarray, max_nfev: int,
                  ftol: float = 1e-8, loss: str = "linear") -> np.ndarray | None:
    """Gauss-Newton with one QR of the column-scaled Jacobian per step, stopping where scipy's ``least_squares``
    does (a step lowering the cost by less than ``ftol`` of it), or ``None`` -- a step that does not lower the cost, a
    nearly singular R, too many evaluations -- and the caller's trust region starts over.  Why: the kept set is
    identifiable by construction (the guard held the rest), so from a start near the minimum (a warm start, the
    robust fit) the full steps converge and the trust region's SVD per step (a third of a 19-joint tree's fold
    fits) buys nothing.  ``loss`` ``soft_l1`` (the outlier step's robust fit): reweighted steps
    (:func:`_robust_weights`) to scipy's minimum; the demo's one robust fit then needs no ``scipy.optimize``, whose
    import (0.3-0.5 s, with ``scipy.spatial`` and ``scipy.sparse``) was a tenth of the whole ``robocal demo``.  The
    triangular solve is numpy's (an LU of a triangular R pivots nothing), for the same reason: ``scipy.linalg`` alone
    is 0.1-0.3 s to import."""
    th = theta_full.copy()
    r, J = problem.residuals(th)
    cost, rs, js = _robust_weights(r, loss)
    # reweighting converges linearly: a step's decrease understates the way left, so it stops at a smaller one
    stop = ftol if loss == "linear" else 1e-3 * ftol
    for _ in range(max_nfev):
        Jk = J[:, kidx] * js[:, None] if loss != "linear" else J[:, kidx]
        norms = np.linalg.norm(Jk, axis=0)
        if not np.all(norms > 0):
            return None
        Ra = np.linalg.qr(np.column_stack([Jk / norms, rs]), mode="r")    # [R | Q^T r]: Q is never formed
        R, qtr = Ra[:-1, :-1], Ra[:-1, -1]
        diag = np.abs(np.diag(R))
        if diag.min() <= 1e-10 * diag.max():
            return None
        step = np.linalg.solve(R, qtr) / norms
        trial = th.copy()
        trial[kidx] -= step
        r_new = problem.residuals(trial, jac=False)[0]
        cost_new, rs_new, js_new = _robust_weights(r_new, loss)
        if not np.isfinite(cost_new) or cost_new > (1.0 + ftol) * cost:
            # at the minimum already, the model promising less than ftol of the cost: what the step added is the
            # rounding of the residuals (noise-free data); else a step too long: shortened along its direction
            if np.isfinite(cost_new) and qtr @ qtr <= ftol * cost:
                return th
            got = _shortened(problem, th, kidx, step, cost, loss)
            if got is None:
                # no shorter step along a descent direction lowers the cost: at the minimum, to the cost's rounding,
                # when the step promised next to nothing (a 19-joint tree's fits: 1-3e-8 of the cost, its rise on
                # the full step 6e-8), else the trust region's work
                return th if qtr @ qtr <= _AT_MINIMUM * cost else None
            th, r, cost, rs, js = got   # never a convergence test after a shortened step: it moves little by design
            J = problem.residuals(th)[1]
            continue
        if cost_new >= cost:
            return th                   # at the minimum already: the step only moved the rounding
        th = trial
        if cost - cost_new <= stop * cost:
            return th
        r, J = problem.residuals(th)
        cost, rs, js = cost_new, rs_new, js_new
    return None


#: how many times a Gauss-Newton step that raised the cost is halved before the trust region takes over
_HALVINGS = 6
#: a full step promising less than this share of the cost, none of whose halvings lowers it, ends at the minimum
#: (the cost is a chi-square, and the promised decrease the step's length in chi-square units: at most
#: sqrt(1e-6 cost), 0.05 sigma on the elastic tree's 2,300, where the steps that ended there promised 1-3e-8 of
#: it: 0.01 sigma; the errors a misfit inflates by the reduced chi-square shrink the share further)
_AT_MINIMUM = 1e-6


def _shortened(problem: _Problem, th: np.ndarray, kidx: np.ndarray, step: np.ndarray, cost: float, loss: str):
    """The Gauss-Newton step halved until it lowers the cost (at most :data:`_HALVINGS` times): ``(theta, r, cost,
    r', w')`` there, or None.  Why: from a linear start a 19-joint tree's geometric fits overshoot on their first full
    steps, and the trust region that took over from the start again spent 15-29 evaluations (8 of the elastic tree's
    37 s of diagnosis); the Gauss-Newton direction is a descent direction, so a short enough step along it lowers the
    cost, and the full steps that follow converge where the trust region would."""
    t = 1.0
    for _ in range(_HALVINGS):
        t *= 0.5
        trial = th.copy()
        trial[kidx] -= t * step
        r = problem.residuals(trial, jac=False)[0]
        c, rs, js = _robust_weights(r, loss)
        if np.isfinite(c) and c < cost:
            return trial, r, c, rs, js
    return None


def _bodies_start(model: MeasurementModel, prob: _Problem, theta: np.ndarray, kidx: np.ndarray,
                  max_nfev: int) -> np.ndarray:
    """An identified mass (a load-stage effect) and the compliances that feel it form a product (deflection =
    compliance x torque): from the start, both near zero, the trust region scales the mass's step by the compliance's
    zero and the mass runs off along the product's valley.  So the compliances (and everything else) are first
    fitted with the masses held at their start, from the masses the description gives; the joint fit starts there."""
    body = [i for e, s in zip(model.effects, model.effect_slices) if e.adds_bodies for i in range(s.start, s.stop)]
    rest = np.array([i for i in kidx if i not in body], int)
    if len(rest) == len(kidx) or not len(rest):
        return theta
    return _solve(prob, theta, rest, "linear", max_nfev)


def pose_chi2(problem: _Problem, theta: np.ndarray, per: int) -> np.ndarray:
    """Whitened residual sum of squares per pose (priors left out)."""
    r, _ = problem.residuals(theta, jac=False)
    return (r[: problem.obs.n * per].reshape(problem.obs.n, per) ** 2).sum(1)


def _outlier_step(model: MeasurementModel, st: _Setup, kidx, theta, mode: str, labels, priors, max_nfev):
    """Step 3b: a robust (soft L1) fit to see the gross errors, the shared decision (:mod:`calib.outliers`), and the
    problem the final fit runs on (without the rejected poses)."""
    prob, obs = st.prob, st.prob.obs
    if mode == "off":
        return prob, theta, OutlierReport("off")
    th_rob = _solve(prob, theta, kidx, "soft_l1", max_nfev)
    report = decide(mode, pose_chi2(prob, th_rob, st.per), st.per,
                    pose_conditions(obs.q_rad, obs.ctx, labels, model.robot))
    if report.rejected:
        keep = np.setdiff1d(np.arange(obs.n), report.rejected)
        prob = _Problem(model, obs.subset(keep), prob.theta0[: model.P], priors)
        prob.theta0 = th_rob.copy()
    return prob, th_rob, report


def _uncertainty(model: MeasurementModel, prob: _Problem, theta: np.ndarray, kidx: np.ndarray,
                 error_scale: str = "inflate", covariance: bool = True):
    """Step 4: covariance (inflated by the reduced chi-square above 1, or scaled by it either way with
    ``error_scale="residual"``), reduced chi-square, unweighted RMS, undetermined directions
    (:func:`calib.covariance.from_jacobian`: column-scaled SVD, never ``pinv(J^T J)``).  ``covariance=False``:
    zeros and no directions (a cross-validation fold's fit, whose parameters only predict its held-out rows)."""
    r, J = prob.residuals(theta, jac=covariance)
    dof = max(1, len(r) - len(kidx))
    red = float(r @ r / dof)
    cov = np.zeros((len(prob.names), len(prob.names)))
    undetermined = []
    if covariance:
        c = from_jacobian(J[:, kidx], [prob.names[i] for i in kidx])
        cov[np.ix_(kidx, kidx)] = c.matrix * (red if error_scale == "residual" else max(1.0, red))
        undetermined = c.undetermined
    # unweighted residual RMS (mm for points, rad for angles)
    if not prob.angles:
        pred = prob.last_points(theta)
        rms = float(np.sqrt(np.mean(np.sum((prob.obs.points_mm - pred) ** 2, axis=1))))
    else:
        sig = np.concatenate([[s.sigma_hz_rad, s.sigma_v_rad] for s in prob.stations(theta)])
        raw = r[: prob.obs.n * len(sig)].reshape(prob.obs.n, -1) * sig
        rms = float(np.sqrt(np.mean(raw ** 2)))
    return cov, red, rms, len(r), undetermined


def identify(model: MeasurementModel, obs: PointObservations | AngleObservations, free: list[str] | None = None,
             theta0: np.ndarray | None = None, robust: bool = True,
             priors: dict[str, tuple[float, float]] | None = None, start: bool = True,
             max_nfev: int = 200, outliers: str = "flag", loss: str = "linear",
             labels: dict[str, list] | None = None, error_scale: str = "inflate",
             warm: np.ndarray | None = None, report: bool = True,
             shared: SharedStart | None = None) -> Identification:
    """Identify the free parameters from the observations (see the module docstring for the pipeline).

    ``outliers``: ``flag`` (report, keep), ``reject`` (leave out flagged poses that do not cluster) or ``off``
    (``robust=False`` is ``off``, as before); ``loss``: scipy's ``linear``, ``huber``, ``cauchy`` or ``soft_l1`` for
    the final fit; ``labels``: per-pose groups (station, target) the outlier cluster test also looks at;
    ``error_scale``: ``inflate`` (the covariance from the given noise, inflated by the reduced chi-square when that
    exceeds 1) or ``residual`` (scaled by the reduced chi-square either way: the noise was not given, the weights only
    say the relative precision of the points); ``warm``: where the solver starts (all parameters, e.g. a fit of the
    same model on more rows: a cross-validation fold), instead of the rigid-fit and linear start -- ``theta0`` stays
    what a held parameter is held at, so the converged fit is the one this start would reach, sooner;
    ``report=False``: a fit whose parameters only predict (a cross-validation fold): the covariance left at zero,
    no undetermined directions, and the identifiability analysis does not look for the joint that would determine a
    held direction (words nobody prints); the held set and the estimate are the same; ``shared``: a
    :class:`SharedStart` passed to fits that differ only in their measured points (re-solves with the points moved):
    their first evaluation and identifiability analysis are computed once -- the same result, sooner.
    """
    st, kidx, prob, theta, out_rep = _to_outliers(model, obs, free, theta0, robust, priors, start, max_nfev,
                                                  outliers, loss, labels, warm, explain=report, shared=shared)
    theta = _solve(prob, theta, kidx, loss, max_nfev)
    cov, red, rms, n_obs, undetermined = _uncertainty(model, prob, theta, kidx, error_scale, report)
    kept = st.ident.kept
    fixed = [n for n in prob.names if n not in kept]
    return Identification(prob.names, theta, kept, fixed, cov, st.ident, rms, red, out_rep.flagged, n_obs,
                          prob.stations(theta), out_rep, undetermined, error_scale, prob)


def outlier_report(model: MeasurementModel, obs: PointObservations | AngleObservations, free: list[str] | None = None,
                   outliers: str = "flag", loss: str = "linear", labels: dict[str, list] | None = None,
                   max_nfev: int = 200) -> OutlierReport:
    """:func:`identify`'s outlier decision alone (its steps 1 to 3b: start, identifiability, the robust fit and the
    shared decision), without the final fit and covariance that only :func:`identify` needs: the report is that
    ``identify(model, obs, free=free, outliers=outliers, loss=loss, labels=labels).outlier_report`` gives."""
    return _to_outliers(model, obs, free, None, True, None, True, max_nfev, outliers, loss, labels, None,
                        explain=False)[4]


def _to_outliers(model: MeasurementModel, obs: PointObservations | AngleObservations, free: list[str] | None,
                 theta0: np.ndarray | None, robust: bool, priors: dict | None, start: bool, max_nfev: int,
                 outliers: str, loss: str, labels: dict | None, warm: np.ndarray | None,
                 explain: bool = True, shared: SharedStart | None = None
                 ) -> tuple[_Setup, np.ndarray, _Problem, np.ndarray, OutlierReport]:
    """identify's steps 1 to 3b: the problem, start point, identifiability, and the outlier decision; returns the
    set-up, the kept columns, the problem the final fit runs on, its start point and the outlier report."""
    check_mode(outliers, loss)
    priors = priors or {}
    theta0 = np.array(model.nominal if theta0 is None else theta0, float)
    # an effect parameter with a prior starts at it (a data-sheet stiffness: a product of compliance and an
    # identified mass cannot leave zero along both; the geometry's priors are its design values already)
    for name, (value, _) in priors.items():
        if model.index.get(name, -1) >= model.n_geometric:
            theta0[model.index[name]] = value
    prob = _Problem(model, obs, theta0, priors)
    st = _Setup(prob, _free_set(model, prob, obs, free), 3 if not prob.angles else 2 * len(obs.stations))
    if warm is not None:
        start = False
    if start and not prob.angles:
        prob.theta0[: model.P] = initial_base(model, obs.q_rad, obs.points_mm, obs.ctx, theta0)
    _check_enough_poses(model, st, priors)
    _identifiability(model, st, priors, start, warm, explain, shared)
    kept = st.ident.kept
    kidx = np.array([prob.names.index(n) for n in kept], int)
    st.theta = _bodies_start(model, prob, st.theta, kidx, max_nfev)
    prob, theta, report = _outlier_step(model, st, kidx, st.theta, outliers if robust else "off", labels, priors,
                                        max_nfev)
    return st, kidx, prob, theta, report
