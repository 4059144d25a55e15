"""What a fit assumed about the noise, said in words (issue 24, item 5).

Why: the parameters' error bars and every chi-square rest on the points' noise.  A default borrowed from another
instrument (a theodolite's 0.05 mm for motion-capture data) made a reduced chi-square of 18,000 pass silently.  So:

* the noise is **given** (sigma columns, polar noise, ``--noise-mm``), or **estimated** from the data without a model
  (repeats, several targets per pose: :mod:`calib.noise`), or **unknown** -- then the points keep their relative
  weights, the scale is the fit's own robust residual scale, and the errors are scaled by the residual; one line says
  which (:func:`noise_line`) and the JSON carries it (:meth:`Weights.as_dict`);
* a reduced chi-square far from 1 is said in words with its likely cause (:func:`chi2_words`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .distributions import chi2_median, chi2_sf
from .identify import PointObservations, identify, pose_chi2
from .noise import combine, given_sigma_mm, model_free
from .rows import point_covariance

#: a reduced chi-square outside this range (and improbable at the fit's degrees of freedom) is said in words
CHI2_FAR = (0.5, 2.0)


@dataclass
class Weights:
    """The observations to fit, and where their noise came from."""

    obs: object                       # calib.identify.PointObservations
    given: bool
    how: str                          # "--noise-mm", "the data's sigma columns", "repeats (...)", "unknown"
    sigma_mm: float                   # per-coordinate 1-sigma in use (RMS over the points)
    table: object = None              # the fit rows (calib.posecsv.PoseTable): a fold re-decides on its own rows
    fit: object = None
    raw: object = None                # the observations with their relative weights, before the decision
    warm: np.ndarray | None = None    # the whole set's plain fit (unknown noise): where a fold's own fit starts
    set_aside: list[str] = field(default_factory=list)   # model-free sources the data gave that do not measure it

    @property
    def error_scale(self) -> str:
        return "inflate" if self.given or self.how != "unknown" else "residual"

    @classmethod
    def decide(cls, table, obs, noise_mm: float | None, fit, measured=None) -> "Weights":
        """Given, estimated without a model, or unknown (see the module docstring); ``fit`` (with ``free``,
        ``priors``, ``theta0``, ``start``, ``model``) is told the error scale.  ``measured``: the rows as the file
        gave them (the fitted ``table`` may carry covariances robocal made: orientation rows' extra points)."""
        own = point_covariance(measured if measured is not None else table) is not None
        if own or noise_mm is not None:
            how = "the data's own uncertainty columns" if own else "--noise-mm"
            w = cls(obs, True, how, given_sigma_mm(obs.cov_mm2), table, fit)
        else:
            found = model_free(table.q_rad, table.points_mm, obs.cov_mm2, pose_id=table.pose_id or None,
                               target=table.target, body=fit.model.robot.tool_point_frames or None, given=False)
            if any(not s.set_aside for s in found):
                est = combine(given_sigma_mm(obs.cov_mm2), found)
                w = cls(_rescaled(obs, est.estimated_mm / given_sigma_mm(obs.cov_mm2)), False, est.how,
                        est.estimated_mm, table, fit)
            else:
                scale, theta = _robust_scale(obs, fit)
                w = cls(_rescaled(obs, scale), False, "unknown", given_sigma_mm(obs.cov_mm2) * scale, table, fit,
                        warm=theta, set_aside=[f"the {s.how}: {s.set_aside}" for s in found])
        fit.error_scale = w.error_scale
        w.raw = obs
        return w

    def for_rows(self, rows) -> object:
        """The observations of ``rows`` weighted as this decision would weigh them on those rows alone."""
        return self.fold(rows, rows[:0])[0]

    def fold(self, train, test) -> tuple[object, object]:
        """A cross-validation fold's observations (train rows, test rows), both weighted by the decision made again
        on the train rows alone: a model-free estimate (repeats, targets) from the train rows, else the robust scale of
        a fit to them.  No held-out row's value enters its own predicted sigma, and the test rows carry the scale
        the fold's reduced chi-square is relative to (the all-row scale times the fold's reduced chi-square mixed
        two decisions: 88 % of the 34-row TIAGo set's held-out coordinates within 2 sigma, 90 % with the fold's)."""
        train, test = np.asarray(train, int), np.asarray(test, int)
        if self.given or self.fit is None or self.raw is None:
            return self.obs.subset(train), self.obs.subset(test)
        raw_tr, raw_te = self.raw.subset(train), self.raw.subset(test)
        if self.how != "unknown":
            t = self.table.subset(train)
            found = model_free(t.q_rad, t.points_mm, raw_tr.cov_mm2, pose_id=t.pose_id or None, target=t.target,
                               body=self.fit.model.robot.tool_point_frames or None, given=False)
            if any(not s.set_aside for s in found):
                f = combine(given_sigma_mm(raw_tr.cov_mm2), found).estimated_mm / given_sigma_mm(raw_tr.cov_mm2)
                return _rescaled(raw_tr, f), _rescaled(raw_te, f)
        f = _robust_scale(raw_tr, self.fit, self.warm)[0]
        return _rescaled(raw_tr, f), _rescaled(raw_te, f)

    def as_dict(self, ident=None) -> dict:
        out = {"given": self.given, "from": self.how, "sigma_mm": self.sigma_mm,
               "errors_scaled_by_residual": self.error_scale == "residual", "set_aside": self.set_aside}
        if ident is not None:
            out["residual_sigma_mm"] = float(self.sigma_mm * np.sqrt(max(ident.reduced_chi2, 0.0)))
        return out


def _rescaled(obs, factor: float):
    return PointObservations(obs.q_rad, obs.points_mm, obs.cov_mm2 * factor ** 2, obs.sigma_mm * factor, obs.ctx)


def _robust_scale(obs, fit, warm: np.ndarray | None = None) -> tuple[float, np.ndarray]:
    """The factor taking the points' relative weights to the scatter a plain fit of the full free set shows, on a
    robust scale (the median pose's chi-square: a few gross errors do not inflate it, so the outlier test that follows
    still sees them), and that fit's parameters.  ``warm``: where the fit starts (a fold: the whole set's fit)."""
    idn = identify(fit.model, obs, free=fit.free, priors=fit.priors, theta0=fit.theta0, start=fit.start,
                   outliers="off", error_scale="residual", warm=warm)
    chi = pose_chi2(idn.problem, idn.theta, 3)          # the fit's last evaluation: its rows, priors apart
    med = float(np.median(chi)) / float(chi2_median(3))
    return (float(np.sqrt(med)) if med > 0 else 1.0), idn.theta


def noise_line(doc: dict) -> str:
    """One line: where the noise came from, and whether the errors are scaled by the residual."""
    if doc["given"]:
        return f"noise: {doc['sigma_mm']:.4g} mm per coordinate, given ({doc['from']})"
    if not doc["errors_scaled_by_residual"]:
        return f"noise: {doc['sigma_mm']:.4g} mm per coordinate, estimated from the data without a model ({doc['from']})"
    res = doc.get("residual_sigma_mm")
    why = ("; ".join(doc["set_aside"]) if doc.get("set_aside") else "no repeats, one target per pose")
    return (f"noise: not given (--noise-mm, sigma columns) and not measurable without a model ({why}): the "
            "parameters' errors are scaled by the fit's residual"
            + (f" ({res:.4g} mm per coordinate)" if res is not None else ""))


def chi2_words(ident, given: bool, noise=None) -> str:
    """A reduced chi-square far from 1 in words, with its cause ("" when near 1, or when the errors are scaled by the
    residual: then it is 1 by construction).  ``noise``: the data's own estimate (:class:`calib.noise.
    NoiseEstimate`), which tells a noise given too small from a model that misses something."""
    red = float(ident.reduced_chi2)
    if getattr(ident, "error_scale", "inflate") == "residual" or not np.isfinite(red):
        return ""
    dof = max(1, int(ident.n_obs) - len(ident.free))
    p_hi = float(chi2_sf(red * dof, dof))
    if CHI2_FAR[0] <= red <= CHI2_FAR[1] or 1e-3 < p_hi < 1 - 1e-3:
        return ""
    ratio = float(np.sqrt(red))
    if red > 1:
        why = ("either the noise given is too small or the model misses something systematic (robocal diagnose looks "
               "for what)")
        if noise is not None and noise.estimated_mm is not None and not noise.upper_bound:
            if noise.given_too_small:
                why = "the noise given is too small: the data show it without a model"
            elif noise.given_too_large:     # the data's own scatter is smaller still: the noise is not the cause
                why = ("the model misses something systematic: the data's own noise estimate is smaller than the given "
                       "one, so a noise given too small is not the cause (robocal diagnose looks for what)")
            else:
                why = ("the model misses something systematic: the data's own noise estimate agrees with the given "
                       "one (robocal diagnose looks for what)")
            why += f" ({noise.estimated_mm:.3g} mm from {noise.how})"
        return (f"reduced chi-square {red:.3g} is far above 1: the residual is {ratio:.3g}x the given noise; {why}; "
                f"the errors are inflated by it")
    return (f"reduced chi-square {red:.3g} is far below 1: the residual is {1 / ratio:.3g}x smaller than the given "
            f"noise, which is too large (or the points are not independent); the errors are not scaled down")
