"""Ruler (section 4.2): L, gamma1, gamma2 and B's height from the marks sighted both faces -- the same fit the
runner uses live (:mod:`acq.session.stations`).  Gives the stations every later stage intersects its targets with,
their fit's covariance carried into every point (:class:`calib.estimators.points.StationFit`)."""
from __future__ import annotations

import numpy as np

from calib.estimators.points import StationFit
from calib.units import ARCSEC, DEG

from acq.session.setup import setup_stations, station_names
from acq.session.setup_types import BenchSetup
from acq.session.stations import fit_ruler, ruler_rows, ruler_station_fit

from offline.reduction.context import Reduction
from offline.reduction.registry import Stage

NAMES = ("L_mm", "gamma1_rad", "gamma2_rad", "hB_mm")


def fitted_stations(steps: list[dict], setup: BenchSetup):
    """The ruler fit of ``steps`` (:class:`calib.uncertainty.EstimateSet`) and the stations it gives with the fit's
    covariance (:class:`calib.estimators.points.StationFit`)."""
    res, stations = fit_ruler(ruler_rows(steps, station_names(setup)), setup)
    return res, ruler_station_fit(res, stations)


def reduce_ruler(ctx: Reduction, steps: list[dict]) -> StationFit | None:
    if not steps:
        return None
    res, fit = fitted_stations(steps, ctx.setup)
    ctx.est.add_set("ruler.", res, only=NAMES)
    L, g1, g2 = (res[n].value for n in NAMES[:3])
    ctx.figs["ruler"] = {"L_mm": L, "gamma1_deg": g1 / DEG, "gamma2_deg": g2 / DEG,
                         "residual_arcsec": (np.asarray(res.extras.get("residual", [])) / ARCSEC).tolist()}
    return fit


def setup_station_fit(ctx: Reduction) -> StationFit:
    """No ruler fit: the set-up's stations, taken as exact."""
    ctx.said("ruler: no estimate; points use the setup's stations")
    return StationFit.exact(setup_stations(ctx.setup))


STAGE = Stage("ruler", reduce_ruler, procedures=("ruler",), gives="stations", fallback=setup_station_fit,
              progress=0.1)
