"""Truths of the running-error runs: transmission error, joint and link compliance, coupling, encoder resolution --
from the twin's scenario effects, or the same fit on the twin's noise-free data where the estimator's quantity is
not the effect's own value."""
from __future__ import annotations

import numpy as np

from calib.effects import JointCompliance, LinkCompliance, Loads, PoseContext, TransmissionError
from calib.errors import RobocalError
from calib.estimators.compliance import single_slope_fit
from calib.estimators.resolution import encoder_resolution

from . import Scoring, truth_of


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


def single_slope_truth(effect: JointCompliance, j: int, T, sign: float, unload, cov) -> dict:
    """What one slope fitted over every load gives on the deflections the twin's compliance makes at the same
    torques, without noise, with the same weights ``cov`` (the twin's two slopes are not what a single slope
    estimates, and which mean of them it is depends on the weights)."""
    n = max(effect.joint, j)
    tau = np.zeros((len(T), n))
    tau[:, j - 1] = T
    ctx_dir = np.zeros((len(T), n))
    ctx_dir[:, j - 1] = np.where(unload, -1.0, 1.0)
    ctx = PoseContext(len(T), n, load_direction=ctx_dir)
    d, _ = effect.joint_delta(np.zeros((len(T), n)), ctx, Loads(tau, np.zeros((len(T), n, 3))), effect.values)
    try:
        clean = single_slope_fit(sign * T, sign * d[:, j - 1], unload, cov)
    except RobocalError:
        return {}
    return {e.name: float(e.value) for e in clean.estimates()}


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
    """The twin's resolution of joint ``j`` as the run's fit sees it: the same fit on the twin's true joint angles
    (the encoders plus the joint's running errors, e.g. its transmission error) at the run's counts ``(steps, n)``,
    without noise.  Why: the slope the run measures is the resolution achieved over the run, which the transmission
    error tilts by more than the fit's error; the description's value alone would not be what it estimates."""
    q = twin.robot.joint_from_counts(np.asarray(counts, float))
    try:
        _, th = twin.true_points(q, twin.context(len(q)))
        clean = encoder_resolution(signed_counts, th[:, j - 1] - th[0, j - 1], cov_rad2, design_rad_per_count)
    except RobocalError:
        return {"rad_per_count": design_rad_per_count, "scale": 1.0}
    return {k: float(clean[k].value) for k in ("rad_per_count", "scale")}


@truth_of("resolution")
def resolution_truth(sc: Scoring, trace: dict) -> None:
    for j, t in trace.items():
        tv = resolution_in_estimator_terms(sc.twin, j, t["counts"], t["signed_counts"], t["cov_rad2"],
                                           t["design_rad_per_count"])
        for k, v in tv.items():
            sc.set(f"resolution.j{j}.{k}", v)
