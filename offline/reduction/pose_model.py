"""The pose set's model: the geometry plus the running errors the session measured, with priors from the dedicated
runs.

Why: the pose set is measured with the gears' transmission error, gravity bending the joints and the uncompensated
wrist coupling all present; a geometry-only fit folds them into the geometry and misses the true parameters by tens
of sigma.  The effects' values are identified with the geometry, held near what the dedicated procedures measured
(priors with those procedures' errors), so a poorly measured stiffness cannot bias the fit.
"""
from __future__ import annotations

import numpy as np

from calib.effects import effect_from_text
from calib.estimators.compliance import MAX_REL_ERROR_TWO_SLOPES
from calib.model import MeasurementModel
from calib.robot import Robot

from acq.session.setup_types import BenchSetup


def running_error_specs(setup: BenchSetup, running: dict, coupling_steps=()) -> list[str]:
    """The running errors the pose set's model carries, as effect specs (:func:`calib.effects.effect_from_text`).

    From the session, never from one robot: the set-up's ``running_errors`` list when it has one; otherwise the
    effects the session itself measured -- a transmission error at the order its run found for each joint of the
    transmission-error run, a joint compliance for each joint whose stiffness was determined, and a cross coupling
    for each pair of the coupling run.
    """
    if setup.running_errors is not None:
        return list(setup.running_errors)
    specs = [f"transmission_error:{j}:{res['omega'].value:.4g}"
             for j, res in sorted((running.get("transmission") or {}).items())]
    specs += [f"joint_compliance:{j}" for j in sorted(running.get("compliance") or {})]
    pairs = sorted({(st["spec"]["meta"]["j"], st["spec"]["meta"]["k"]) for st in coupling_steps})
    specs += [f"cross_coupling:{k}:{j}" for j, k in pairs]
    return specs


def sine_cosine(A: float, phi: float) -> tuple[tuple[float, float], np.ndarray]:
    """``A sin(w q + phi)`` as the model's sine and cosine coefficients ``(A cos phi, A sin phi)`` and their
    Jacobian with respect to ``(A, phi)`` (2x2): the one place the run's harmonic meets the model's."""
    c, s = np.cos(phi), np.sin(phi)
    return (A * c, A * s), np.array([[c, -A * s], [s, A * c]])


def harmonic_prior(res) -> list[tuple[str, float, float]]:
    """The transmission-error run's first harmonic as the pose-set model's sine and cosine coefficients with their
    1-sigma: ``A sin(w q + phi) = A cos(phi) sin(w q) + A sin(phi) cos(w q)``, the amplitude's and the phase's errors
    (and their correlation) both propagated -- a phase known to 0.1 rad moves the coefficients by a tenth of A."""
    names = list(res.names)
    i, k = names.index("amplitude1_rad"), names.index("phase1_rad")
    (s1, c1), G = sine_cosine(float(res.value[i]), float(res.value[k]))
    C = res.cov[np.ix_([i, k], [i, k])]
    sd = np.sqrt(np.maximum(np.diag(G @ C @ G.T), 1e-12))
    return [("s1_rad", s1, float(sd[0])), ("c1_rad", c1, float(sd[1]))]


def pose_model(robot: Robot, running: dict, problems: list[str], specs=None):
    """``(model, theta0, priors)``: the model with the running errors ``specs`` (default from ``running``), its
    start values and the priors from the session's transmission-error and compliance runs (see the module
    docstring).  A run whose order disagrees with the model's gives no prior (said in ``problems``)."""
    specs = running_error_specs({}, running) if specs is None else specs
    effects = [effect_from_text(t, robot.n, robot) for t in specs]
    model = MeasurementModel(robot, effects)
    theta0 = model.nominal.copy()
    priors: dict[str, tuple[float, float]] = {}
    for e in effects:
        lab = e.label
        if e.kind == "transmission_error" and e.joint in (running.get("transmission") or {}):
            res = running["transmission"][e.joint]
            w, sw = res["omega"].value, res["omega"].error
            if abs(w - e.order) > 3 * sw + 0.05 * e.order:
                problems.append(f"poses: joint {e.joint} transmission error measured at order {w:.3g} +- {sw:.2g}, "
                                f"the model uses {e.order:g}: no prior from the transmission-error run")
                continue
            for name, v, sv in harmonic_prior(res):
                name = f"{lab}.{name}"
                theta0[model.index[name]] = v
                priors[name] = (v, sv)
        elif e.kind == "joint_compliance" and e.joint in (running.get("compliance") or {}):
            res = running["compliance"][e.joint]
            K, sK = res["K1_Nm_per_rad"].value, res["K1_Nm_per_rad"].error
            if K > 0 and np.isfinite(sK):
                name = f"{lab}.compliance1_rad_per_nm"
                c = 1.0 / K
                theta0[model.index[name]] = c
                theta0[model.index[f"{lab}.compliance2_rad_per_nm"]] = c
                # one slope over every load (the breakpoint not placed) says little of the slope at the pose set's
                # smaller torques: it may differ by as much as two slopes the run could not tell apart
                floor = MAX_REL_ERROR_TWO_SLOPES if res.extras.get("single_slope") else 0.05
                priors[name] = (c, float(max(sK / K ** 2, floor * c)))
    return model, theta0, priors
