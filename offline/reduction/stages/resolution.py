"""Encoder resolution (Fig 5.14): per joint, the measured angle (A1, A2 about the run's own axis, fitted from A2 over
the run) against the tapped counts, the axis's error propagated into the slope's
(:func:`calib.estimators.resolution.encoder_resolution_fitted_axis`)."""
from __future__ import annotations

import numpy as np

from calib.estimators.resolution import design_resolution_rad, encoder_resolution_fitted_axis
from calib.units import DEG

from offline.reduction.context import Reduction
from offline.reduction.joints import by_joint
from offline.reduction.registry import Stage


def reduce_resolution(ctx: Reduction, steps: list[dict]) -> None:
    if not steps:
        return
    robot, points = ctx.robot, ctx.points
    ctx.figs["resolution"] = {}
    ctx.trace["resolution"] = {}
    for j, sts in sorted(by_joint(steps).items()):
        sts = [s for s in sts if s.get("counts") is not None and len(s["counts"]) and {"A1", "A2"} <= set(points(s))]
        pairs = [(points(s)["A1"], points(s)["A2"]) for s in sts]
        counts = np.array([np.mean(s["counts"], 0) for s in sts])
        design = design_resolution_rad(robot.counts_per_rev[j - 1], robot.gear_ratio[j - 1])
        signed = counts[:, j - 1] * np.sign(robot.gear_ratio[j - 1])
        res = encoder_resolution_fitted_axis(signed, [a.point_mm for a, _ in pairs], [b.point_mm for _, b in pairs],
                                             points.covariance([t for p in pairs for t in p]), design, joint=f"j{j}")
        meas, C = res.extras["angle_rad"], res.extras["angle_cov_rad2"]
        ctx.est.add_set(f"resolution.j{j}.", res, only=("rad_per_count", "scale"))
        ctx.trace["resolution"][j] = {"counts": counts, "signed_counts": signed, "cov_rad2": C,
                                      "design_rad_per_count": design}
        ctx.figs["resolution"][j] = {"counts": counts[:, j - 1].tolist(), "angle_deg": (meas / DEG).tolist(),
                                     "sigma_deg": (np.sqrt(np.diag(C)) / DEG).tolist(),
                                     "rad_per_count": float(res["rad_per_count"].value),
                                     "residual_deg": (res.extras["residual_rad"] / DEG).tolist()}


STAGE = Stage("resolution", reduce_resolution, procedures=("encoder_resolution",), needs=("stations",),
              label="encoder resolution")
