"""The theodolite stations from the session's ruler sightings (section 4.2), shared by acquisition and reprocessing.

Why here: the acquisition checks start with the stations the technician wrote down (L from a tape, gammas from
mutual sighting, B's height assumed equal to A's).  Those are good to a few mm, which is all a "did both instruments
sight the same target?" check can ask of them.  As soon as the ruler steps are saved, the same least-squares fit the
reprocessing uses (:func:`calib.estimators.ruler.ruler_lsq`) gives stations good to hundredths of a mm, and the
miss-distance check can then be held to what the reading noise explains (see :mod:`acq.session.checks`).
"""
from __future__ import annotations

import json
from dataclasses import replace

import numpy as np

from calib.errors import RobocalError
from calib.estimators.points import StationFit
from calib.estimators.ruler import RulerSightings, ruler_lsq
from calib.theodolite import Station, thesis_stations
from calib.units import ARCSEC

from .setup import station_names
from .setup_types import BenchSetup, setup_of
from .store import json_column


def ruler_rows(steps: list[dict], names: tuple[str, str] = ("A", "B")) -> np.ndarray:
    """(placement, mark, station 0/1, face, hz, v) per reading of accepted ruler steps (``spec`` and ``readings``);
    station 0 is the first of ``names`` (the set-up's, :func:`acq.session.setup.station_names`)."""
    rows = []
    for st in steps:
        m = st["spec"]["meta"]
        for r in st["readings"]:
            rows.append((m["placement"], m["mark"], 0 if r["station"] == names[0] else 1, r["face"], r["hz_rad"],
                         r["v_rad"]))
    return np.array(rows, float).reshape(-1, 6)


#: the last fit, by its inputs: the same ruler readings are fitted by the runner's last refit, the reduction, the
#: demo's compensated ISO 9283 run (its runner refits at start) and the ISO 9283 figures after it -- a pure function
#: of the rows and the set-up, whose result callers only read
_LAST: dict[bytes, tuple] = {}


def fit_ruler(rows: np.ndarray, setup: BenchSetup):
    """The ruler fit (:class:`EstimateSet`) and the stations it gives; raises RobocalError when underdetermined."""
    a = np.ascontiguousarray(rows, float)
    key = a.tobytes() + repr((tuple(setup.ruler.marks_mm), setup.stations, station_names(setup))).encode()
    if key not in _LAST:
        fitted = _fit_ruler(a, setup)
        _LAST.clear()
        _LAST[key] = fitted
    return _LAST[key]


def _fit_ruler(rows: np.ndarray, setup: BenchSetup):
    if len(rows) == 0:
        raise RobocalError("ruler: no sightings")
    sigma = setup.stations.sigma_arcsec * ARCSEC
    a = np.asarray(rows, float)
    s = RulerSightings(a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4], a[:, 5])
    res = ruler_lsq(s, list(setup.ruler.marks_mm), sigma)
    L, g1, g2 = (res[n].value for n in ("L_mm", "gamma1_rad", "gamma2_rad"))
    hb = res["hB_mm"].value if "hB_mm" in res.names else 0.0
    A, B = thesis_stations(L, g1, g2, sigma, hb)
    na, nb = station_names(setup)
    return res, {na: replace(A, name=na), nb: replace(B, name=nb)}


def ruler_station_fit(res, stations: dict[str, Station]):
    """The fitted stations with the covariance of L, gamma1, gamma2 and B's height from the ruler fit
    (:class:`calib.estimators.points.StationFit`), so every point carries the stations' uncertainty."""
    names = ["L_mm", "gamma1_rad", "gamma2_rad", "hB_mm"]
    keys = list(stations)                           # the set-up's names, the first at the origin
    sigma = stations[keys[0]].sigma_hz_rad
    sub = res.subset(names)

    def build(v):
        return {k: replace(s, name=k) for k, s in zip(keys, thesis_stations(v[0], v[1], v[2], sigma, v[3]))}

    return StationFit(names, sub.value.copy(), sub.cov.copy(), build)


def stations_from_store(store, setup: BenchSetup | dict, min_marks: int = 6) -> dict[str, Station] | None:
    """Stations refitted from the ruler steps committed so far, or None while they cannot determine them.

    ``min_marks``: accepted ruler steps needed before a fit is tried (two placements of three marks): one placement
    leaves the ruler's position and the base length L in one combination.
    """
    conn = store.conn
    steps = []
    for step_id, spec, attempts in conn.execute(
            "SELECT step_id, spec_json, attempts FROM step WHERE procedure='ruler' AND status='accepted' "
            "ORDER BY seq"):
        readings = [{"station": s, "face": f, "hz_rad": h, "v_rad": v} for s, f, h, v in conn.execute(
            "SELECT station, face, hz_rad, v_rad FROM reading WHERE step_id=? AND attempt=? ORDER BY reading_id",
            (step_id, attempts))]
        steps.append({"spec": json_column(spec, f"{store.path}: step {step_id}: spec_json"), "readings": readings})
    if len(steps) < min_marks:
        return None
    setup = setup_of(setup)
    try:
        return fit_ruler(ruler_rows(steps, station_names(setup)), setup)[1]
    except (RobocalError, KeyError, ValueError, np.linalg.LinAlgError):
        return None
