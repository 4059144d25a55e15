"""The measurement noise as the data show it, against the noise a fit was given (shared by identify and diagnose).

Why: the floor a diagnosis measures every gap against, and the uncertainties identify reports, come from the points'
covariances or ``--noise-mm``.  A wrong value moves them: too small and noise looks like an unexplained gap (and the
error bars are too short), too large and real effects hide below the floor.  So the data are asked too, first
without any model of the robot (each source an estimate of the per-coordinate variance with its degrees of freedom):

* **Repeats** (rows with the same joint readings and the same target): the pooled spread about each group's mean,
  per coordinate; ``sum of squares / (3 (rows - 1))`` per group.
* **Several targets per pose** (two or more tool targets rigidly fixed to the tool, rows sharing a pose id): their
  distances are the same at every pose whatever the robot's errors, so their scatter over the poses is noise.  Per
  pose the distance vector ``d_i`` (all pairs) has, to first order (distances >> sigma), the covariance
  ``V_i = G_i C_i G_i^T`` (``G``: +u/-u the pair's unit vector at its two points, ``C_i``: the points' covariances,
  independent).  With ``d_bar`` their weighted mean, ``chi2 = sum_i (d_i - d_bar)^T V_i^+ (d_i - d_bar)`` has
  expectation ``k (n - 1) r`` when the true covariance is ``k C`` (``r``: rank of ``V``: 1 for two targets,
  ``3 t - 6`` for ``t >= 3`` off a line), so the variance is ``k_hat = chi2 / ((n - 1) r)`` times the given
  per-coordinate variance (the mean over those points).  For an isotropic sigma and two targets this is
  ``var(d) = 2 sigma^2``: ``sigma^2 = sum (d_i - d_bar)^2 / (2 (n - 1))``.  A pose whose own chi2 lies beyond the
  0.999 quantile at the scale the others show is left out as a blunder (up to three rounds).  Poses are grouped by
  their set of targets, so a file whose poses carry different targets still gives what it can (a pose with one
  target, or a target twice, gives nothing here).
  Not seen: anything that moves the targets against each other (a tool that bends).
* **Both faces** (raw theodolite readings on face I and face II, a session database): the difference of the face-I
  and the reduced face-II reading of one sighting is twice the collimation/trunnion term (``2 c / sin V +
  2 i cot V``, fitted per station) or twice the index error (a constant per station) plus noise; the residual
  spread estimates each station's angular noise, which goes to mm through the intersection of each pose's sightings
  (:func:`calib.estimators.points.locate_targets`, the reading part of its covariance); the stations' own part of
  the covariance in use (their ruler fit) is kept as given.

The model-free sources are pooled by their degrees of freedom.  Without any, the residual of the fitted model (held
out, or the fit's own with its degrees of freedom) is an **upper bound**: it holds the noise plus whatever the model
misses, so it can refute a given noise that is too large, never one that is too small.  A disagreement by more than
:data:`DISAGREE` either way is a one-line warning.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .angles import circular_mean, wrap_angle
from .distributions import chi2_isf
from .errors import GeometryError, RobocalError
from .estimators.points import StationFit, locate_targets
from .rows import point_covariance
from .units import ARCSEC

#: ratio between given and estimated noise above which identify and diagnose warn
DISAGREE = 1.5
#: targets closer than this multiple of the noise are not used for distances (the first-order variance fails)
MIN_DISTANCE_SIGMAS = 20.0
#: a target-distance scatter this many times below the given noise is not believed as the instrument's noise: the
#: targets move as one rigid body (motion capture that solves a marker set as a body and exports its virtual points,
#: or points derived from one measured frame), so their noise is shared and the distances cannot see it
RIGID_SET_RATIO = 100.0
#: ... nor a scatter below this share of the distances themselves (0.1 um on 100 mm: no instrument that measures a
#: robot's tool in space resolves it), which holds also when no noise is given
RIGID_SET_RELATIVE = 1e-6


@dataclass
class Sample:
    """One source's estimate of the per-coordinate variance (mm^2) and its degrees of freedom."""

    how: str
    var_mm2: float
    dof: int
    set_aside: str = ""             # why this source is not pooled ("" when it is)

    def as_dict(self) -> dict:
        out = {"from": self.how, "estimated_mm": float(np.sqrt(self.var_mm2)), "dof": self.dof}
        return out | ({"set_aside": self.set_aside} if self.set_aside else {})


@dataclass
class NoiseEstimate:
    given_mm: float                 # per-coordinate 1-sigma in use (RMS over the points' covariances)
    estimated_mm: float | None      # per-coordinate 1-sigma from the data (None: no source and no residual)
    how: str                        # the sources used, e.g. "repeats (4 poses, 8 rows) + target distances (...)"
    upper_bound: bool
    sources: list[Sample] = field(default_factory=list)
    set_aside: list[Sample] = field(default_factory=list)   # sources the data gave but that do not measure the noise

    @property
    def ratio(self) -> float:
        return self.given_mm / self.estimated_mm if self.estimated_mm else float("nan")

    @property
    def given_too_large(self) -> bool:
        return self.estimated_mm is not None and self.ratio > DISAGREE

    @property
    def given_too_small(self) -> bool:
        return not self.upper_bound and self.estimated_mm is not None and self.ratio < 1 / DISAGREE

    def warning(self, source: str, consequence: str = "the gap is judged against the data's noise") -> str:
        """One line, or "" when the given noise is consistent with the data."""
        if self.given_too_large:
            return (f"{source}: the given noise {self.given_mm:.4g} mm is {self.ratio:.1f}x the "
                    f"{'upper bound' if self.upper_bound else 'estimate'} {self.estimated_mm:.4g} mm from the "
                    f"{self.how}; {consequence}")
        if self.given_too_small:
            return (f"{source}: the given noise {self.given_mm:.4g} mm is {1 / self.ratio:.1f}x smaller than the "
                    f"estimate {self.estimated_mm:.4g} mm from the {self.how}; {consequence}")
        return ""

    def floor_scale(self) -> float:
        """Factor for the floor a diagnosis judges against: 1 when consistent, the estimate's ratio with a model-free
        estimate, 0 when only an upper bound refutes the given noise (see calib.diagnose.noise)."""
        if self.given_too_large and self.upper_bound:
            return 0.0
        if self.given_too_large or self.given_too_small:
            return 1.0 / self.ratio
        return 1.0

    def as_dict(self) -> dict:
        return {"given_mm": self.given_mm, "estimated_mm": self.estimated_mm, "from": self.how,
                "upper_bound": self.upper_bound, "sources": [s.as_dict() for s in self.sources],
                "set_aside": [s.as_dict() for s in self.set_aside]}

    def set_aside_lines(self) -> list[str]:
        """One line per source left out of the estimate, with its reason."""
        return [f"noise from the {s.how} ({np.sqrt(s.var_mm2):.3g} mm) not used: {s.set_aside}" for s in self.set_aside]


@dataclass
class Sightings:
    """Raw theodolite readings behind each pose's point: per pose the reading dicts (``station``, ``target``,
    ``face``, ``hz_rad``, ``v_rad``) of ``target[i]``; ``stations`` the :class:`calib.theodolite.Station` objects the
    points were intersected with (name -> Station)."""

    readings: list[list[dict]]
    target: list[str]
    stations: dict

    def subset(self, idx) -> "Sightings":
        return Sightings([self.readings[i] for i in idx], [self.target[i] for i in idx], self.stations)


# -- inputs ---------------------------------------------------------------------------------------------------------
def given_sigma_mm(cov_mm2: np.ndarray) -> float:
    """Per-coordinate 1-sigma of the covariances in use (RMS over points and coordinates)."""
    return float(np.sqrt(np.mean(np.trace(cov_mm2, axis1=1, axis2=2)) / 3.0))


def pose_keys(q_rad: np.ndarray, pose_id=None) -> list:
    """What makes rows one pose: the pose id when the data has one, else the joint readings (to 1e-7 rad)."""
    if pose_id is not None and len(pose_id) == len(q_rad):
        return list(pose_id)
    return [tuple(np.round(q, 7)) for q in q_rad]


def repeat_groups(q_rad: np.ndarray, target=None) -> list[np.ndarray]:
    """Rows measured at the same joint readings (to 1e-7 rad) and the same target: groups of two or more."""
    key = pose_keys(q_rad)
    if target is not None:
        key = [k + (t,) for k, t in zip(key, target)]
    groups: dict = {}
    for i, k in enumerate(key):
        groups.setdefault(k, []).append(i)
    return [np.array(g) for g in groups.values() if len(g) >= 2]


# -- sources --------------------------------------------------------------------------------------------------------
def from_repeats(q_rad: np.ndarray, points_mm: np.ndarray, target=None) -> Sample | None:
    groups = repeat_groups(q_rad, target)
    if not groups:
        return None
    ss = sum(float(np.sum((points_mm[g] - points_mm[g].mean(0)) ** 2)) for g in groups)
    dof = 3 * sum(len(g) - 1 for g in groups)
    rows = sum(len(g) for g in groups)
    return Sample(f"repeats ({len(groups)} poses, {rows} rows)", ss / dof, dof)


def target_sets(keys: list, target: list[str], body: dict[str, int] | None = None) -> dict[tuple, list[np.ndarray]]:
    """Poses with two or more distinct targets on one rigid body, grouped by their (sorted) set of targets: set ->
    per pose the row indices in that order.  A pose naming a target twice is left out (it is a repeat, not a shape).
    ``body``: the body (frame) each target is fixed on -- targets on two arms of a tree keep no distance."""
    rows: dict = {}
    for i, (k, t) in enumerate(zip(keys, target)):
        rows.setdefault((k, None if body is None else body.get(t)), {}).setdefault(t, []).append(i)
    out: dict[tuple, list[np.ndarray]] = {}
    for by_target in rows.values():
        if len(by_target) < 2 or any(len(v) != 1 for v in by_target.values()):
            continue
        names = tuple(sorted(by_target))
        out.setdefault(names, []).append(np.array([by_target[t][0] for t in names]))
    return out


def _distance_chi2(P: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Per pose the chi2 of the pair distances of ``P (n, t, 3)`` with covariances ``C (n, t, 3, 3)`` about their
    weighted mean, per pose the rank of their covariance, and the rank the mean takes (see the module docstring)."""
    t = P.shape[1]
    a, b = np.triu_indices(t, 1)
    diff = P[:, a] - P[:, b]                                    # (n, m, 3)
    d = np.linalg.norm(diff, axis=-1)                           # (n, m)
    u = diff / d[..., None]
    S = np.zeros((len(a), t))                                   # d(pair distance) / d(target) signs
    S[np.arange(len(a)), a], S[np.arange(len(a)), b] = 1.0, -1.0
    A = S[None, :, :, None] * u[:, :, None, :]                  # (n, m, t, 3): d d_p / d P_x
    V = np.einsum("npxi,nxij,nqxj->npq", A, C, A)
    ev = np.linalg.eigvalsh(V)                                  # rank per pose: 1 for two targets, 3 t - 6 for
    rank = np.sum(ev > 1e-9 * ev[:, -1:], axis=1)               # more (fewer when they lie on a line)
    W = np.linalg.pinv(V, hermitian=True, rcond=1e-9)
    Wsum = W.sum(0)
    dbar = np.linalg.lstsq(Wsum, np.einsum("npq,nq->p", W, d), rcond=1e-9)[0]
    e = d - dbar
    return np.einsum("np,npq,nq->n", e, W, e), rank, int(np.linalg.matrix_rank(Wsum, rtol=1e-9))


def _clipped_chi2(P: np.ndarray, C: np.ndarray, p_blunder: float = 1e-3) -> tuple[float, int, int]:
    """chi2 and degrees of freedom of the distances, a pose left out when its chi2 is beyond the ``1 - p_blunder``
    quantile at the scale the others show (a blunder would otherwise pass for noise); returns also how many."""
    keep = np.ones(len(P), bool)
    for _ in range(3):
        c, r, r_mean = _distance_chi2(P[keep], C[keep])
        f = int(r.sum()) - r_mean
        if f <= 0:
            return float("nan"), 0, int((~keep).sum())
        bad = c > chi2_isf(p_blunder, r) * (c.sum() / f)
        if not bad.any() or keep.sum() - bad.sum() < 3:
            break
        keep[np.flatnonzero(keep)[bad]] = False
    return float(c.sum()), f, int((~keep).sum())


def from_target_distances(keys: list, target, points_mm: np.ndarray, cov_mm2: np.ndarray,
                          body: dict[str, int] | None = None, given: bool = True) -> Sample | None:
    """Several targets per pose on one body: the scatter of their distances (see the module docstring).  A scatter
    no instrument shows (:data:`RIGID_SET_RATIO` below the given noise when ``given``, or :data:`RIGID_SET_RELATIVE`
    of the distances) is returned set aside: those targets move as one rigid body."""
    if target is None:
        return None
    var, dof, poses, dropped, used, g_var, dist = 0.0, 0, 0, 0, set(), 0.0, []
    for names, idx in target_sets(keys, list(target), body).items():
        if len(idx) < 3:
            continue
        I = np.array(idx)                                       # (n, t) row indices
        P, C = points_mm[I], cov_mm2[I]
        g2 = float(np.mean(np.trace(C, axis1=-2, axis2=-1)) / 3.0)
        dmin = min(np.linalg.norm(P[:, i] - P[:, j], axis=-1).min() for i in range(len(names))
                   for j in range(i + 1, len(names)))
        if not dmin > MIN_DISTANCE_SIGMAS * np.sqrt(g2):
            continue
        dist.append(dmin)
        chi2, f, out = _clipped_chi2(P, C)
        if not (f > 0 and np.isfinite(chi2)):
            continue
        var += chi2 * g2                                        # k_hat * g2, weighted by f
        g_var += f * g2
        dof += f
        poses += len(idx) - out
        dropped += out
        used.update(names)
    if dof == 0:
        return None
    blunders = f", {dropped} left out as blunders" if dropped else ""
    sigma, rel = float(np.sqrt(var / dof)), float(np.sqrt(var / dof)) / float(np.median(dist))
    ratio = float(np.sqrt(g_var / var)) if var > 0 else float("inf")
    if given and ratio > RIGID_SET_RATIO:
        why = f"the distances between the targets scatter {ratio:,.0f}x less than the given noise"
    elif rel < RIGID_SET_RELATIVE:
        why = f"the distances between the targets scatter {rel:.1e} of their length, which no instrument resolves"
    else:
        why = ""
    rigid = (why + ": the targets move as one rigid body (virtual points of a solved marker set, or points derived "
             "from one measured frame), so their noise is shared and the distances cannot see it") if why else ""
    return Sample(f"target distances ({poses} poses{blunders}, targets {', '.join(sorted(used))})", sigma ** 2, dof,
                  rigid)


def _face_differences(s: Sightings) -> dict[str, list[tuple]]:
    """Per station: (dHz, dV, V, weight) of every sighting read on both faces (face means of its repeats)."""
    out: dict[str, list[tuple]] = {}
    for rs, tg in zip(s.readings, s.target):
        by: dict = {}
        for r in rs:
            if r["target"] == tg:
                by.setdefault((r["station"], int(r["face"])), []).append(r)
        for st in {k[0] for k in by}:
            f1, f2 = by.get((st, 1)), by.get((st, 2))
            if not f1 or not f2:
                continue
            h1 = circular_mean([r["hz_rad"] for r in f1])
            h2 = circular_mean([r["hz_rad"] - np.pi for r in f2])
            v1 = float(np.mean([r["v_rad"] for r in f1]))
            v2 = float(np.mean([2 * np.pi - r["v_rad"] for r in f2]))
            w = 1.0 / (1.0 / len(f1) + 1.0 / len(f2))
            out.setdefault(st, []).append((float(wrap_angle(h1 - h2)), v1 - v2, 0.5 * (v1 + v2), w))
    return out


def _weighted_residual(y: np.ndarray, X: np.ndarray, w: np.ndarray) -> tuple[float, int]:
    """Weighted least-squares fit of y on X: residual sum of squares (weighted) and degrees of freedom."""
    sw = np.sqrt(w)
    coef, _, rank, _ = np.linalg.lstsq(X * sw[:, None], y * sw, rcond=1e-9)
    e = (y - X @ coef) * sw
    return float(e @ e), len(y) - int(rank)


def station_noise(s: Sightings) -> dict[str, tuple[float, float, int, int]]:
    """Per station: (sigma_hz_rad, sigma_v_rad, dof_hz, dof_v) of one reading, from its face differences after
    removing the collimation/trunnion term (``2c / sin V + 2i cot V``) and the index error (constant)."""
    out = {}
    for st, rows in _face_differences(s).items():
        dh, dv, v, w = (np.array(c, float) for c in zip(*rows))
        ss_h, f_h = _weighted_residual(dh, np.column_stack([1 / np.sin(v), np.cos(v) / np.sin(v)]), w)
        ss_v, f_v = _weighted_residual(dv, np.ones((len(dv), 1)), w)
        if f_h >= 2 and f_v >= 2:
            out[st] = (np.sqrt(ss_h / f_h), np.sqrt(ss_v / f_v), f_h, f_v)
    return out


def from_faces(s: Sightings | None, cov_mm2: np.ndarray | None = None) -> Sample | None:
    """Both faces: each station's angular noise from its face differences, through each pose's intersection to mm.

    The point's covariance in use (``cov_mm2``) may hold more than the reading noise (the stations' own uncertainty
    from the ruler fit): that part is kept as given, only the reading part is replaced by the one the faces show."""
    if s is None or not s.readings:
        return None
    per = station_noise(s)
    if len(per) < 2:
        return None
    named = {nm: st for nm, st in s.stations.items() if nm in per}
    found = _reading_cov(s, {nm: replace(st, sigma_hz_rad=per[nm][0], sigma_v_rad=per[nm][1])
                             for nm, st in named.items()})
    if not found:
        return None
    if cov_mm2 is not None:
        given = _reading_cov(s, named)
        extra = [np.trace(cov_mm2[i]) - np.trace(given[i]) for i in found if i in given]
    else:
        extra = [0.0]
    var = float(np.mean([np.trace(c) for c in found.values()]) + np.mean(extra)) / 3.0
    dof = sum(f_h + f_v for _, _, f_h, f_v in per.values())
    arcsec = ", ".join(f"{nm} {per[nm][0] / ARCSEC:.2g}/{per[nm][1] / ARCSEC:.2g}" for nm in named)
    return Sample(f"both faces ({len(found)} poses; Hz/V noise {arcsec} arcsec)", var, dof)


def _reading_cov(s: Sightings, stations: dict) -> dict[int, np.ndarray]:
    """Pose index -> the reading part of its point's covariance, intersected with ``stations`` (their sigmas)."""
    readings = [{**r, "target": f"{i}\x00{r['target']}"} for i, (rs, tg) in enumerate(zip(s.readings, s.target))
                for r in rs if r["target"] == tg and r["station"] in stations]
    pts = locate_targets(readings, StationFit.exact(stations)) if readings else {}
    return {int(k.split("\x00")[0]): p.cov_reading_mm2 for k, p in pts.items()}


# -- together -------------------------------------------------------------------------------------------------------
def model_free(q_rad: np.ndarray, points_mm: np.ndarray, cov_mm2: np.ndarray, *, pose_id=None, target=None,
               sightings: Sightings | None = None, body: dict[str, int] | None = None,
               given: bool = True) -> list[Sample]:
    """Every source the data allow; a source the data cannot feed (inconsistent targets, a degenerate geometry) is
    left out rather than stopping the caller; one that does not measure the noise is returned set aside
    (:attr:`Sample.set_aside`).  ``body``: the frame each target is fixed on (a branched robot's points on different
    arms keep no distance; :attr:`calib.robot.Robot.tool_point_frames`).  ``given``: ``cov_mm2`` is a noise someone
    gave (False: relative weights only)."""
    out = []
    if target is not None and len(target) != len(q_rad):        # labels that do not match the rows: not used
        target = None
    keys = pose_keys(q_rad, pose_id)
    for make in (lambda: from_repeats(q_rad, points_mm, target),
                 lambda: from_target_distances(keys, target, points_mm, cov_mm2, body, given),
                 lambda: from_faces(sightings, cov_mm2)):
        try:
            s = make()
        except (np.linalg.LinAlgError, GeometryError, RobocalError, ValueError, KeyError, TypeError):
            s = None
        if s is not None and np.isfinite(s.var_mm2) and s.dof > 0:
            out.append(s)
    return out


def combine(given_mm: float, sources: list[Sample], bound_mm: float | None = None,
            bound_how: str = "held-out residual (upper bound)") -> NoiseEstimate:
    """The model-free sources pooled by degrees of freedom; without any, ``bound_mm`` (per-coordinate, from a
    residual) as an upper bound; without that either, no estimate.  Sources set aside (:attr:`Sample.set_aside`) are
    kept for the words, never pooled."""
    aside = [s for s in sources if s.set_aside]
    sources = [s for s in sources if not s.set_aside]
    if sources:
        dof = sum(s.dof for s in sources)
        var = sum(s.var_mm2 * s.dof for s in sources) / dof
        return NoiseEstimate(given_mm, float(np.sqrt(var)), " + ".join(s.how for s in sources), False, sources, aside)
    if bound_mm is None or not np.isfinite(bound_mm):
        return NoiseEstimate(given_mm, None, "", True, set_aside=aside)
    return NoiseEstimate(given_mm, float(bound_mm), bound_how, True, set_aside=aside)


def for_rows(table, noise_mm: float, bound_mm: float | None = None,
             bound_how: str = "fit residual (upper bound)", body: dict[str, int] | None = None,
             given: bool = True) -> NoiseEstimate:
    """The estimate for the rows of a pose table (:class:`calib.posecsv.PoseTable`, as identify reads it): the points'
    covariances (sigma columns, polar noise) or ``noise_mm`` are the given noise; pose ids and targets group the
    rows."""
    cov = point_covariance(table)
    if cov is None:
        cov = np.broadcast_to(np.eye(3) * noise_mm ** 2, (table.n, 3, 3))
    found = model_free(table.q_rad, table.points_mm, cov, pose_id=table.pose_id or None, target=table.target,
                       body=body, given=given)
    return combine(given_sigma_mm(cov), found, bound_mm, bound_how)
