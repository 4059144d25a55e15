"""Transmission error (section 4.4): per joint, the angle turned from A1, A2 about the joint's own axis against the
joint readings (tapped encoder counts), and the harmonic fit of the difference with the angles' full covariance
(:func:`calib.estimators.transmission.fit_transmission_error`); Section 4.4's E_a (measured minus commanded) as
well.  Turning the joint turns the arm's weight about the joints whose stiffness the session measured: their
deflection about this joint's axis is taken out first (:func:`offline.reduction.torques.compliance_deflection`), else it
reads as a first-order periodic error.  A joint whose fit fails, or whose order is not determined, is said so and left out of the running errors the
pose set carries; the other joints still count.  Gives the fits by joint."""
from __future__ import annotations

import numpy as np

from calib.errors import RobocalError
from calib.estimators.coupling import quantisation_sigma
from calib.estimators.resolution import design_resolution_rad
from calib.estimators.transmission import commanded_angle_errors, fit_transmission_error
from calib.units import DEG

from offline.reduction.context import Reduction, step_ids
from offline.reduction.joints import angles_about, angles_about_own_axis, by_joint, encoder_q, reading_q, relative_error
from offline.reduction.registry import Stage
from offline.reduction.torques import compliance_deflection, swept_geometry, swept_loads


def reference_quantisation(steps: list[dict], ctx: Reduction, j: int) -> np.ndarray:
    """Covariance the encoder's quantisation adds to ``meas - (enc - enc[0])`` over a run: each step's count is off
    by up to half a count (uniform: 1/sqrt(12) of a count), and the first step's error enters every difference.  A
    Puma wrist count is 0.005 deg at the joint, as large as the theodolites' angle noise; steps whose joint reading
    is the commanded angle (no tap) carry none."""
    robot = ctx.robot
    s = quantisation_sigma(design_resolution_rad(robot.counts_per_rev[j - 1], robot.gear_ratio[j - 1]))
    tapped = np.array([encoder_q(st, robot) is not None for st in steps], float)
    E = np.diag(-tapped)
    E[:, 0] += tapped[0]
    E[0] = 0.0
    return s ** 2 * (E @ E.T)


def commanded(ctx: Reduction, steps, meas, cov, ok, j: int) -> None:
    """Section 4.4's E_a (measured minus commanded angle) of a transmission run, its slope as an estimate."""
    desired = np.array([s["spec"]["pose_deg"][j - 1] for s in steps], float)[ok] * DEG
    try:
        ea = commanded_angle_errors(meas[ok], cov[np.ix_(ok, ok)], desired)
    except RobocalError as exc:
        ctx.said(f"transmission: joint {j}: E_a: {exc}")
        return
    ctx.est.add_set(f"te.j{j}.", ea, only=("E_a_slope",))
    ctx.figs["transmission"][j]["E_a_deg"] = [0.0] + (ea.value[:-1] / DEG).tolist()


def run_angles(ctx: Reduction, sts: list[dict], j: int, axes: dict):
    """A run's angles about joint j's own axis fitted over the run, else about its swept axis (``axes``): (angles,
    sigmas, covariance), kept (:meth:`offline.reduction.context.Reduction.keep`)."""
    own = ctx.keep(("own axis", step_ids(sts), j), lambda: angles_about_own_axis(sts, ctx.points, j))
    if own is not None:
        return own
    axis = axes[j].value[3:6]
    return ctx.keep(("about", step_ids(sts), axis.tobytes()), lambda: angles_about(sts, ctx.points, axis))


def _swept_axes(ctx: Reduction) -> dict:
    return ctx.outputs["axes"].axes if ctx.outputs.get("axes") is not None else {}


def prepare_transmission(ctx: Reduction, steps: list[dict]) -> None:
    """What the stage computes from its own steps, the stations and the sweeps alone -- the runs' angles and the
    arm's loads along them -- done while the stage waits for the compliance stage (see
    :mod:`offline.reduction.live`)."""
    axes, swept = _swept_axes(ctx), swept_geometry(ctx)
    for j, sts in sorted(by_joint(steps).items()):
        if j in axes:
            run_angles(ctx, sts, j, axes)
            swept_loads(ctx, sts, swept, errors=False)


def reduce_transmission(ctx: Reduction, steps: list[dict]) -> dict | None:
    if not steps:
        return None
    axes = _swept_axes(ctx)
    stiffness = ctx.outputs.get("compliance") or {}
    swept = swept_geometry(ctx)
    ctx.figs["transmission"] = {}
    fits, failed = {}, []
    for j, sts in sorted(by_joint(steps).items()):
        if j not in axes:
            failed.append(f"joint {j}: no swept axis to measure the angle about")
            continue
        meas, sig, cov = run_angles(ctx, sts, j, axes)
        enc = np.array([reading_q(s, ctx.robot)[j - 1] for s in sts])
        err = relative_error(meas, enc)
        cov = cov + reference_quantisation(sts, ctx, j)
        if stiffness:                       # the gravity deflection of the measured joints, as the joint turns
            bent, bcov = compliance_deflection(swept_loads(ctx, sts, swept, errors=False), stiffness, j)
            err, cov = err - bent, cov + bcov
        ok = np.isfinite(err)
        try:
            res = fit_transmission_error(enc[ok], err[ok], cov[np.ix_(ok, ok)], n_mc=ctx.n_mc)
        except RobocalError as exc:
            failed.append(f"joint {j}: {exc}")
            continue
        ctx.est.add_set(f"te.j{j}.", res, only=("omega", "amplitude1_rad"))
        nd = res.extras.get("not_determined") or {}
        if "omega" not in nd:
            fits[j] = res
        ctx.figs["transmission"][j] = {"encoder_deg": (enc / DEG).tolist(), "error_deg": (err / DEG).tolist(),
                                       "sigma_deg": (sig / DEG).tolist(),
                                       "fit": {k: float(res[k].value) for k in res.names}, "not_determined": nd}
        commanded(ctx, sts, meas, cov, ok, j)
    if failed and not fits:
        raise RobocalError("; ".join(failed))
    for f in failed:
        ctx.said(f"transmission: {f}")
    return fits


PREPARE = prepare_transmission
STAGE = Stage("transmission", reduce_transmission, procedures=("transmission",), needs=("axes", "compliance"),
              gives="transmission")
