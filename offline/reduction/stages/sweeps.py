"""Joint sweeps (section 4.3, circle point analysis): per joint a circle and its axis fitted to the swept target
(:func:`calib.estimators.axes.fit_axis`), then the DH parameters from successive axes
(:func:`calib.estimators.dh.dh_estimate`) when every joint was swept.  Gives the axes with the design frames at the
reference pose, which the misalignment table, the compensation scheme and the later runs use."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.estimators.axes import fit_axis
from calib.estimators.dh import dh_estimate
from calib.kinematics import ChainPass, Kinematics
from calib.units import DEG

from acq.session.setup import nominal_theta
from acq.session.setup_types import BenchSetup

from offline.reduction.context import Reduction
from offline.reduction.joints import by_joint
from offline.reduction.registry import Stage


@dataclass
class SweptAxes:
    """The fitted axes (joint -> :class:`calib.uncertainty.EstimateSet` of centre, direction, radius) and the
    design's frames at the reference pose the joints were swept about (``design``: the description with the bench's
    base from the set-up)."""

    axes: dict
    kin: Kinematics
    p_design: np.ndarray
    q0_rad: np.ndarray
    design: ChainPass

    def stacked(self, joints) -> tuple[np.ndarray, np.ndarray]:
        """Centres and directions of ``joints`` (1-based) as one vector (6 per joint) and its block covariance."""
        V = np.concatenate([self.axes[j].value[:6] for j in joints])
        C = np.zeros((len(V), len(V)))
        for i, j in enumerate(joints):
            C[6 * i:6 * i + 6, 6 * i:6 * i + 6] = self.axes[j].cov[:6, :6]
        return V, C

    def design_frames(self) -> tuple[np.ndarray, np.ndarray]:
        """Design axis directions ``z (n, 3)`` and common normals ``x (n, 3)`` at the reference pose."""
        n = self.kin.robot.n
        R = self.design.frame_R[0]
        return np.array([R[j][:, 2] for j in range(n)]), np.array([R[j + 1][:, 0] for j in range(n)])


def reference_pose(sweep_steps: list[dict], setup: BenchSetup) -> np.ndarray:
    """The pose the joints were swept about (rad): the set-up's ``reference_pose_deg`` when given, else from the
    session's own sweep steps -- every sweep holds the other joints at it and centres its own joint on it."""
    if setup.reference_pose_deg is not None:
        return np.asarray(setup.reference_pose_deg, float) * DEG
    return np.median(np.array([st["spec"]["pose_deg"] for st in sweep_steps], float), axis=0) * DEG


def reduce_sweeps(ctx: Reduction, steps: list[dict]) -> SweptAxes | None:
    if not steps:
        return None
    robot, points = ctx.robot, ctx.points
    axes = {}
    ctx.figs["sweeps"] = {}
    for j, sts in sorted(by_joint([st for st in steps if "joint" in st["spec"]["meta"]]).items()):
        pts = [points(s)["P"] for s in sts]
        P = np.array([p[0] for p in pts])
        res = fit_axis(P, points.covariance(pts), n_mc=ctx.n_mc, joint=f"j{j}")
        axes[j] = res
        v = res.value
        ctx.figs["sweeps"][j] = {"points_mm": P.tolist(), "centre_mm": v[:3].tolist(), "normal": v[3:6].tolist(),
                                 "radius_mm": float(v[6]),
                                 "residual_mm": np.asarray(res.extras.get("residual_mm", [])).ravel().tolist()}
    kin = Kinematics(robot)
    p = nominal_theta(kin, ctx.setup)
    q0 = reference_pose(steps, ctx.setup)
    swept = SweptAxes(axes, kin, p, q0, kin.forward(q0[None], p))
    ctx.trace["sweeps"] = {"q0_rad": q0.tolist()}
    if len(axes) < robot.n:
        return swept
    fn = swept.design
    V, C = swept.stacked(range(1, robot.n + 1))
    dh = dh_estimate(V, C, q0, fn.frame_R[0, 0], fn.frame_t[0, 0], fn.frame_R[0, 1:-1, :, 0], robot.hayati[:-1],
                     robot.d_mm[:-1], alpha_ref=robot.alpha_rad[:-1], n_mc=ctx.n_mc)
    ctx.est.add_set("dh.", dh)
    nominal = dict(zip(kin.names, kin.nominal))
    ctx.figs["dh"] = [{"name": n, "value": float(dh[n].value), "error": float(dh[n].error),
                       "nominal": float(nominal.get(n, np.nan)), "truth": None} for n in dh.names]
    return swept


STAGE = Stage("sweeps", reduce_sweeps, procedures=("sweep",), needs=("stations",), gives="axes", progress=0.3)
