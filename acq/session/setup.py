"""The bench set-up as the acquisition sees it: approximate stations from the set-up file (until the ruler steps
refit them) and where the nominal model expects each tool target, with the tolerance of an uncalibrated description.
Used by every session, real or emulated (not only the demo)."""
from __future__ import annotations

import numpy as np

from calib.model import MeasurementModel
from calib.theodolite import thesis_stations
from calib.units import ARCSEC, DEG

from .steps import Step


def setup_stations(setup: dict) -> dict:
    """Approximate stations from the setup (for the acquisition checks; reprocessing uses the ruler's)."""
    s = setup["stations"]
    a, b = thesis_stations(s["L_mm"], s["gamma1_deg"] * DEG, s["gamma2_deg"] * DEG, s["sigma_arcsec"] * ARCSEC)
    return {"A": a, "B": b}


#: 1-sigma gap between a robot description and the real robot, before calibration: link lengths (a Puma's a3 can be
#: 10 mm off its drawing), twists and zero offsets (the thesis found misalignments up to 1.2 deg), the base placed
#: with a tape and a level, the tool target from its drawing.
DESCRIPTION_TOLERANCES = {"length_mm": 5.0, "angle_deg": 0.3, "base_mm": 10.0, "base_angle_deg": 0.3,
                          "tool_mm": 2.0}


def _prior_sigmas(names: list[str], tol: dict) -> np.ndarray:
    out = []
    for n in names:
        if n.startswith("base."):
            out.append(tol["base_mm"] if n.endswith("_mm") else tol["base_angle_deg"] * DEG)
        elif n.startswith("tool."):
            out.append(tol["tool_mm"])
        else:
            out.append(tol["length_mm"] if n.endswith("_mm") else tol["angle_deg"] * DEG)
    return np.asarray(out)


def predictor(robot, setup: dict, tolerances: dict | None = None):
    """Where the nominal model with the setup's base puts each tool target of a step, and how far off an
    uncalibrated description can be there: target -> (point_mm, sigma_mm) for the plausibility check.

    sigma is the root of the trace of J S J^T, J the point's Jacobian in the geometric parameters and S the
    description's tolerances (:data:`DESCRIPTION_TOLERANCES`): a point far from the base gets a wider limit."""
    m = MeasurementModel(robot)
    th = m.nominal.copy()
    for k, v in zip(("x_mm", "y_mm", "z_mm"), setup["base_xyz_mm"]):
        th[m.index[f"base.{k}"]] = v
    sd = _prior_sigmas(list(m.kin.names), {**DESCRIPTION_TOLERANCES, **(tolerances or {})})

    def predict(step: Step) -> dict:
        if step.pose_deg is None:
            return {}
        out = {}
        for t in step.targets:
            if t.tool_mm is not None:
                ev = m.evaluate(np.asarray(step.pose_deg)[None] * DEG, theta=th, jacobian=True,
                                tool_mm=np.asarray(t.tool_mm))
                J = ev.jacobian[0][:, : m.n_geometric] * sd[None, :]
                out[t.name] = (ev.point_mm[0], float(np.sqrt(np.sum(J * J))))
        return out
    return predict
