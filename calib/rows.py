"""A pose table's rows through the one forward model: each row's conditions, the tool point its ``target`` names
and the instrument set-up it was measured from (:func:`context_of`), its prediction (:func:`predict_rows`), and the
measured points' covariance (:func:`point_covariance`).

Why a module of its own: evaluation (``robocal evaluate``/``locate``), the orientation rows' axis points
(:mod:`calib.orientation`), the noise estimate and the fit report all predict or weigh rows; each imports this, none
of them the others.
"""
from __future__ import annotations

import numpy as np

from .effects.target_offset import TargetOffset
from .errors import RobocalError
from .model import MeasurementModel
from .posecsv import PoseTable
from .targets import TargetContext, reference_name, station_index, target_index


def point_covariance(table: PoseTable) -> np.ndarray | None:
    """(N, 3, 3) covariance of the measured points: polar noise, else the sigma_*_mm columns, else None."""
    if table.cov_mm2 is not None:
        return table.cov_mm2
    if table.sigma_mm is not None:
        return np.einsum("ni,ij->nij", table.sigma_mm ** 2, np.eye(3))
    return None


def tool_per_row(robot, table: PoseTable) -> np.ndarray | None:
    """(N, 3) tool point in frame n for each row's ``target``; None when the file names no targets."""
    if table.target is None:
        return None
    out = np.empty((table.n, 3))
    for i, t in enumerate(table.target):
        if t not in robot.tool_points_mm:
            known = ", ".join(robot.tool_points_mm) or "none"
            raise RobocalError(f"{table.source}: line {table.line[i] if table.line else i + 1}: target {t!r} names "
                               f"no tool point of the model (tool points: {known})")
        out[i] = robot.tool_points_mm[t]
    return out


def context_of(model: MeasurementModel, table: PoseTable, new_stations: bool = False) -> TargetContext:
    """The pose conditions of every row, with the index of the tool point it measures and of the model's station
    it was measured from (by name).  A station the model does not know is an error naming it, or, with
    ``new_stations`` (the rows are re-stationed afterwards: locate, evaluate --locate), the reference set-up."""
    tool_per_row(model.robot, table)                          # names every target, or fails naming the line
    return TargetContext(table.n, model.robot.n, direction=table.direction, payload_kg=table.payload_kg,
                         temperature_c=table.temperature_c, time_s=table.time_s,
                         target=target_index(model.robot, table.target, table.n),
                         station=_model_stations(model, table, new_stations))


def _model_stations(model: MeasurementModel, table: PoseTable, new_stations: bool) -> np.ndarray:
    idx, names = station_index(table.station, table.n, model.stations)
    unknown = np.flatnonzero(idx < 0)
    if unknown.size and not new_stations:
        i = unknown[0]
        known = (f"its stations: {', '.join(names)}" if names else
                 "it was identified from one set-up without a station column")
        raise RobocalError(f"{table.source}: line {table.line[i] if table.line else i + 1}: column station: "
                           f"{table.station[i]!r} is not a station of the model ({known}); --locate re-stations it")
    idx[unknown] = 0
    return idx


def predict_rows(model: MeasurementModel, theta: np.ndarray, table: PoseTable, new_stations: bool = False) -> np.ndarray:
    """Predicted positions (N, 3) of every row's target in the frame of the model's station of that row (see
    :func:`context_of` for ``new_stations``).

    The reference target and those with an offset effect come from ``theta``; any other named target from the
    model's tool points."""
    ctx = context_of(model, table, new_stations)
    tool = None
    if table.target is not None:
        names = list(model.robot.tool_points_mm)
        ref = names.index(reference_name(names))
        in_theta = {ref} | {e.target for e in model.effects if isinstance(e, TargetOffset)}
        if not set(ctx.target) <= in_theta:
            i = model.kin.index["tool.x_mm"]
            own = np.asarray(theta[i:i + 3], float)
            tool = np.array([own if k in in_theta else model.robot.tool_points_mm[names[k]] for k in ctx.target])
    return model.points(table.q_rad, ctx, theta, tool)
