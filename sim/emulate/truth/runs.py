"""Truths of the running-error runs: transmission error, joint and link compliance, coupling, encoder resolution --
from the twin's scenario effects by the thesis's own formulas.  Where the estimator's quantity is not the effect's own
value (one slope over a two-slope joint, the resolution achieved over a run the transmission error tilts), the truth
is the weighted straight line through the twin's exact values (:func:`weighted_line`, plain algebra), never the
reduction's estimator run on noise-free data: the truth must not share the code it judges."""
from __future__ import annotations

import numpy as np

from calib.effects import JointCompliance, LinkCompliance, TransmissionError

from sim.emulate.truth import Scoring, truth_of


def first_harmonic_amplitude(effect: TransmissionError) -> float:
    """The amplitude of the effect's first harmonic, ``hypot(s1, c1)`` (its values run s1, c1, s2, c2 ...)."""
    v = dict(zip(effect.param_names, effect.values))
    return float(np.hypot(v["s1_rad"], v["c1_rad"]))


@truth_of("transmission")
def transmission_truth(sc: Scoring, trace: dict) -> None:
    for e in sc.twin.scenario.effects:
        if isinstance(e, TransmissionError):
            sc.set(f"te.j{e.joint}.omega", e.order)
            sc.set(f"te.j{e.joint}.amplitude1_rad", first_harmonic_amplitude(e))


def weighted_line(columns: list, y, cov) -> np.ndarray | None:
    """The coefficients of ``y = sum_k b_k columns[k]`` by generalised least squares with the covariance ``cov``
    (a matrix, or the rows' variances): ``b = (X' C^-1 X)^-1 X' C^-1 y``, solved whitened.  None when the columns do
    not determine them."""
    y = np.asarray(y, float)
    X = np.stack([np.broadcast_to(np.asarray(c, float), y.shape) for c in columns], -1)
    C = np.asarray(cov, float)
    C = np.diag(np.broadcast_to(C, y.shape)) if C.ndim < 2 else C
    W = np.linalg.inv(np.linalg.cholesky(C))
    b, _, rank, _ = np.linalg.lstsq(W @ X, W @ y, rcond=None)
    return b if rank == X.shape[1] else None


def two_slope_deflection(effect: JointCompliance, T, unloading) -> np.ndarray:
    """Section 4.5's joint deflection under torque ``T`` from the twin's parameters: slope c1 up to the breakpoint
    and c2 beyond it, in the torque's direction; the unloading branch ``h`` above the loading one."""
    c1, c2, tb, h = effect.values
    T = np.asarray(T, float)
    a, tb = np.abs(T), tb if np.isfinite(tb) else np.inf
    d = np.where(a <= tb, c1 * T, np.sign(T) * (c1 * tb + c2 * (a - tb)) if np.isfinite(tb) else c1 * T)
    return d + h * (np.where(np.asarray(unloading, bool), 0.5, -0.5))


def single_slope_truth(effect: JointCompliance, j: int, T, sign: float, unload, cov) -> dict:
    """What one slope over every load is of the twin's deflections at the same torques, with the same weights
    ``cov``: the weighted line ``d = theta0 + offset u + T / K1`` through them (the twin's two slopes are not what a
    single slope estimates, and which mean of them it is depends on the weights).  Empty when the loads do not
    determine a slope."""
    T = np.asarray(T, float)
    u = np.asarray(unload, bool).astype(float)
    b = weighted_line([np.ones_like(T), u, sign * T], sign * two_slope_deflection(effect, T, unload), cov)
    if b is None or not b[2] > 0:
        return {}
    return {"K1_Nm_per_rad": float(1.0 / b[2]), "offset_rad": float(b[1]), "theta0_rad": float(b[0])}


@truth_of("compliance")
def compliance_truth(sc: Scoring, trace: dict) -> None:
    """The twin's stiffness in the estimator's terms: its own slopes, breakpoint and dead zone when the fit told the
    two slopes apart; when it could not place the breakpoint, the single-slope fit on the twin's noise-free
    deflections at the same torques (:func:`single_slope_truth`)."""
    for e in sc.twin.scenario.effects:
        if not isinstance(e, JointCompliance) or e.joint not in trace:
            continue
        j, t = e.joint, trace[e.joint]
        c1, c2, tb, h = e.values
        # the fit reads unloading minus loading in its own sign (d = c(T) - h/2 x load direction)
        raw = {"K1_Nm_per_rad": 1 / c1, "K2_Nm_per_rad": 1 / c2, "breakpoint_Nm": tb, "offset_rad": t["sign"] * h}
        tv = dict(raw)
        if t["single_slope"]:
            clean = single_slope_truth(e, j, np.asarray(t["torque_nm"]), t["sign"], np.asarray(t["unloading"]),
                                       t["cov_rad2"])
            if not clean:                   # no noise-free fit: no truth in the estimator's terms
                continue
            tv.update({k: v for k, v in clean.items() if k in raw})
        for name, r in raw.items():
            est = sc.estimate(f"compliance.j{j}.{name}")
            if est is None:
                continue
            if abs(tv[name] - r) > 0.1 * est["error"]:
                sc.set(est["name"], tv[name], raw=r,
                       note="truth: the same fit on the twin's noise-free deflections at the same torques")
            else:
                sc.set(est["name"], tv[name])


@truth_of("link")
def link_truth(sc: Scoring, trace: dict) -> None:
    """The scenario's link compliance of the tested link; a rigid link (no truth, said) when it has none."""
    joint = sc.setup.link.joint if sc.setup.link is not None else None
    ei = [1.0 / float(e.values[0]) for e in sc.twin.scenario.effects
          if isinstance(e, LinkCompliance) and e.joint == joint]
    prefix = f"link.j{joint}."
    sc.set(f"{prefix}EI_Nmm2", ei[0] if ei else None)
    sc.set_bound(f"{prefix}EI_lower_bound_Nmm2", ei[0] if ei else None,
                 None if ei else "rigid: the scenario has no link compliance")


@truth_of("coupling")
def coupling_truth(sc: Scoring, trace: dict) -> None:
    """The coupling the twin's encoders count with (its description's factors)."""
    C = sc.twin.robot.coupling
    for e in sc.res["estimates"]:
        name = e["name"]
        if name.startswith("coupling.sigma") and len(name) == len("coupling.sigma") + 2:
            j, k = int(name[-2]), int(name[-1])
            sc.set(name, float(C[k - 1, j - 1]))


def resolution_in_estimator_terms(twin, j: int, counts, signed_counts, cov_rad2, design_rad_per_count: float) -> dict:
    """The twin's resolution of joint ``j`` as the run sees it: the slope of the weighted line (:func:`weighted_line`,
    the run's weights ``cov_rad2``) through the twin's true joint angles (the encoders plus the joint's running
    errors, e.g. its transmission error) at the run's counts ``(steps, n)``.  Why: the slope the run measures is the
    resolution achieved over the run, which the transmission error tilts by more than the fit's error; the
    description's value alone would not be what it estimates."""
    q = twin.robot.joint_from_counts(np.asarray(counts, float))
    _, th = twin.true_points(q, twin.context(len(q)))
    c = np.asarray(signed_counts, float)
    b = weighted_line([np.ones_like(c), c - c[0]], th[:, j - 1] - th[0, j - 1], cov_rad2)
    if b is None:
        return {"rad_per_count": design_rad_per_count, "scale": 1.0}
    return {"rad_per_count": float(b[1]), "scale": float(b[1] / design_rad_per_count)}


@truth_of("resolution")
def resolution_truth(sc: Scoring, trace: dict) -> None:
    for j, t in trace.items():
        tv = resolution_in_estimator_terms(sc.twin, j, t["counts"], t["signed_counts"], t["cov_rad2"],
                                           t["design_rad_per_count"])
        for k, v in tv.items():
            sc.set(f"resolution.j{j}.{k}", v)
