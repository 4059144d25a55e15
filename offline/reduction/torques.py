"""Torques about the joints at a loading step, from the geometry: the description's link weights plus the hung masses
as point forces (:mod:`calib.loads`), through the model's one load computation -- and what their errors are (the
geometry as known, the lever, the masses weighed).  Used by the joint-compliance stage."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.loads import hung_masses, point_force_context
from calib.model import MeasurementModel
from calib.units import DEG

from acq.session.setup import DESCRIPTION_TOLERANCES, nominal_theta

from offline.reduction.context import Reduction, step_ids
from offline.reduction.joints import reading_q


@dataclass
class StepLoads:
    """One loading step: joint readings (rad), total torque about every joint (N m), the joints' axes (n, 3) in the
    measurement frame, the torques' derivatives w.r.t. the geometric parameters (n, P_geometric) and the load points'
    coordinates in their frames (n, 3, summed over the loads: they move together when the lever is measured wrong),
    and the hung masses' torque per kg hung (n,: what a wrong mass changes, the thesis's Delta N)."""

    q_rad: np.ndarray
    torque_nm: np.ndarray
    axes: np.ndarray
    dtau_dgeo: np.ndarray | None            # None: not computed (:func:`step_loads` ``errors=False``)
    dtau_dpoint: np.ndarray | None
    hung_nm_per_kg: np.ndarray | None


def swept_geometry(ctx: Reduction) -> tuple[MeasurementModel, np.ndarray, np.ndarray]:
    """The model the torques are computed with (the description, the bench's base from the set-up), its parameters
    and each one's 1-sigma: the session's own DH estimates from the sweeps where it has them (they run first), the
    description within its tolerances (:data:`acq.session.setup.DESCRIPTION_TOLERANCES`) elsewhere.  Why: a Puma's
    a3 can be 10 mm off its drawing, which is 2 % of a compliance lever."""
    model = MeasurementModel(ctx.robot)
    theta = nominal_theta(model, ctx.setup)
    tol = DESCRIPTION_TOLERANCES
    sig = np.array([tol["length_mm"] if n.startswith("j") and n.endswith("_mm") else
                    tol["angle_deg"] * DEG if n.startswith("j") and n.endswith("_rad") else 0.0
                    for n in model.kin.names])
    for name, e in ctx.est.named("dh.").items():
        if name in model.kin.index and not e["held"] and np.isfinite(e["error"]):
            theta[model.index[name]], sig[model.kin.index[name]] = e["value"], e["error"]
    return model, theta, sig


def swept_loads(ctx: Reduction, steps: list[dict], swept: tuple[MeasurementModel, np.ndarray, np.ndarray],
                errors: bool = True) -> list[StepLoads]:
    """:func:`series_loads` with ``swept`` (:func:`swept_geometry`'s model, parameters and errors), kept by the steps
    and the parameters (:meth:`offline.reduction.context.Reduction.keep`: a stage's ``PREPARE`` computes them while
    the stage waits for other procedures)."""
    model, theta, _ = swept
    return ctx.keep(("loads", step_ids(steps), errors, theta.tobytes()),
                    lambda: series_loads(steps, ctx, model, theta, errors))


def step_loads(step: dict, ctx: Reduction, model: MeasurementModel, theta: np.ndarray,
               errors: bool = True) -> StepLoads:
    """The loads of one step (see :class:`StepLoads`).  ``errors=False``: the torques and axes only (what
    :func:`compliance_deflection` uses), the derivatives the torques' errors come from left as None -- the torque
    derivative is most of the cost, and the transmission stage's correction for the loaded joints needs none."""
    return series_loads([step], ctx, model, theta, errors)[0]


def series_loads(steps: list[dict], ctx: Reduction, model: MeasurementModel, theta: np.ndarray,
                 errors: bool = True) -> list[StepLoads]:
    """:func:`step_loads` of every step of a series, in order: the steps whose masses hang on the same links go
    through the model together (one chain pass and one load computation for a loading series instead of one per
    step; each pose's loads are its own, the model being vectorised over poses)."""
    g = model.gravity_n_per_kg(theta)
    masses = [hung_masses(s["spec"]["setup"].get("loads", [])) for s in steps]   # in the step vocabulary
    groups: dict[tuple, list[int]] = {}
    for i, ms in enumerate(masses):
        groups.setdefault(tuple(m.link for m in ms), []).append(i)
    out: list[StepLoads | None] = [None] * len(steps)
    for idx in groups.values():
        for i, sl in zip(idx, _group_loads([steps[i] for i in idx], [masses[i] for i in idx], ctx, model, theta, g,
                                           errors)):
            out[i] = sl
    return out


def _group_loads(steps, masses, ctx, model, theta, g, errors) -> list[StepLoads]:
    """:func:`series_loads` of steps whose masses hang on the same links."""
    robot = ctx.robot
    q = np.array([reading_q(s, robot) for s in steps])
    forces = [point_force_context(ms, g) for ms in masses]
    both = {"point_force_link": forces[0]["point_force_link"],
            **{k: np.concatenate([f[k] for f in forces]) for k in ("point_force_mm", "point_force_n")}}
    fp = model.kin.forward(q, theta[: model.n_geometric])
    ld = model.loads(fp, model.context(len(steps), **both), derivative=errors)
    if not errors:
        return [StepLoads(q[s], ld.joint_torque_nm[s], fp.joint_axis[s], None, None, None) for s in range(len(steps))]
    hung = ld.joint_torque_nm - model.loads(fp, model.context(len(steps))).joint_torque_nm
    out = []
    for s, (ms, f) in enumerate(zip(masses, forces)):
        mass_kg = float(sum(m.mass_kg for m in ms))
        # moving a load's point by e_c in its frame j adds (R_j e_c x F) . z_i to joint i's torque (i <= j)
        z = fp.joint_axis[s]
        dpoint = np.zeros((robot.n, 3))
        for m, fn in zip(ms, f["point_force_n"][0]):
            R = fp.frame_R[s, m.link]
            for i in range(min(m.link, robot.n)):
                dpoint[i] += np.cross(R.T, fn * 1e-3) @ z[i]
        out.append(StepLoads(q[s], ld.joint_torque_nm[s], z, ld.dtau_dgeo[s], dpoint,
                             hung[s] / mass_kg if mass_kg > 0 else 0 * hung[s]))
    return out


def torque_covariance(per_step: list[StepLoads], j: int, sig_geo: np.ndarray) -> np.ndarray:
    """Covariance of the torques about joint j over a loading series, from the geometry they were computed with
    (``sig_geo``, per geometric parameter) and the load point's position (a lever measured with a tape: the tool
    tolerance), each common to the whole series -- the thesis's Delta L_j and Delta theta_ij terms, from the model's
    torque derivative instead of N L cos(theta); and the mass hung at each step (the thesis's Delta N: each step's
    weights weighed to ``load_mass_kg``, independent from step to step)."""
    tol = DESCRIPTION_TOLERANCES
    Jg = np.array([p.dtau_dgeo[j - 1] for p in per_step]) * sig_geo                 # (steps, P)
    Jp = np.array([p.dtau_dpoint[j - 1] for p in per_step]) * tol["tool_mm"]        # (steps, 3)
    dN = np.array([p.hung_nm_per_kg[j - 1] for p in per_step]) * tol["load_mass_kg"]
    return Jg @ Jg.T + Jp @ Jp.T + np.diag(dN ** 2)


def compliance_deflection(per_step: list[StepLoads], fits: dict, j: int, skip: int | None = None):
    """What the joints whose stiffness the session measured (``fits``: joint -> two-slope fit) turn about joint j's
    axis over a series of steps, from the first: ``sum_i (z_i . z_j) (T_i - T_i[0]) / K_i`` -- a deflection of joint
    i about its own axis turns a line on the tool by its projection on j's axis, so joints whose axes are parallel
    to j's (a UR arm's shoulder, elbow and first wrist joint) add their whole deflection to any angle measured about
    it.  Returns the deflection (steps,) and its covariance from the stiffnesses' errors; ``skip``: a joint left out
    (the one being fitted).  Why: a series loads every joint up the chain, and a turn of the joint being measured
    changes the gravity torque on the others."""
    T = np.array([p.torque_nm for p in per_step])                  # (steps, n)
    z = np.array([p.axes for p in per_step])                       # (steps, n, 3)
    out, cov = np.zeros(len(per_step)), np.zeros((len(per_step), len(per_step)))
    for i, res in sorted(fits.items()):
        if i == skip:
            continue
        K, sK = res["K1_Nm_per_rad"].value, res["K1_Nm_per_rad"].error
        v = np.einsum("sc,sc->s", z[:, i - 1], z[:, j - 1]) * (T[:, i - 1] - T[0, i - 1])
        if not np.any(np.abs(v) > 1e-9 * max(K, 1.0)):
            continue
        out += v / K
        cov += np.outer(v, v) * (sK / K ** 2) ** 2
    return out, cov
