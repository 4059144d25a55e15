"""Held-out evaluation and re-stationing of a calibrated model against a pose CSV (``robocal evaluate`` / ``locate``).

* **Prediction** of every row through the one forward model (:mod:`calib.rows`), each row with the tool point its
  ``target`` names.
* **Locate** (re-stationing): per ``station`` group, the rigid transform from the model's measurement frame to that
  instrument set-up, fitted by least squares to the rows with the calibrated model held fixed (Kabsch, via scipy's
  ``Rotation.align_vectors``).  A located station absorbs 6 degrees of freedom, so its residual is computed from rows
  that did not locate it where there are any (the station's ``fit`` rows locate it, its ``test`` rows are scored).
* **Summary**: RMS, max and 95th percentile of the 3-D residual length, overall and per group (station, target and any
  text column of the file).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import orientation as ori
from .accuracy import error_stats
from .angles import rigid_fit, rpy_from_matrix, wrap_angle
from .errors import RobocalError
from .heldout import HeldOut
from .model import MeasurementModel
from .posecsv import PoseTable
from .angles import rpy_from_matrix
from .effects.station_offset import StationOffset
from .polar import PolarNoise, polar_points
from .rows import context_of, point_covariance, predict_rows
from .units import DEG
from .targets import station_effects, station_index, with_targets


def with_polar_points(table: PoseTable, noise=None) -> PoseTable:
    """A table whose polar readings (hz_deg, v_deg, dist_mm) are turned into points with their covariance
    (:mod:`calib.polar`) when it has no x, y, z; the table itself otherwise."""
    if table.points_mm is None and table.polar is not None:
        table.points_mm, table.cov_mm2 = polar_points(table.polar, noise or PolarNoise())
    return table


@dataclass
class Location:
    """One station's set-up: measured = R @ predicted + t."""

    station: str
    R: np.ndarray
    t_mm: np.ndarray
    n_rows: int
    rms_mm: float

    def apply(self, p: np.ndarray) -> np.ndarray:
        return p @ self.R.T + self.t_mm

    def as_dict(self) -> dict:
        # R = Rz(yaw) Ry(pitch) Rx(roll), the base convention
        roll, pitch, yaw = rpy_from_matrix(self.R) / DEG
        return {"station": self.station, "xyz_mm": [float(v) for v in self.t_mm],
                "rpy_deg": [float(roll), float(pitch), float(yaw)], "n_rows": self.n_rows, "rms_mm": self.rms_mm}


def fit_location(station: str, pred: np.ndarray, meas: np.ndarray) -> Location:
    """The rigid transform taking predicted points onto measured ones (least squares)."""
    if len(pred) < 3:
        raise RobocalError(f"locate: station {station!r} has {len(pred)} measured points; at least 3 are needed")
    R, t = rigid_fit(pred, meas)
    res = meas - (pred @ R.T + t)
    return Location(station, R, t, len(pred), float(np.sqrt(np.mean(np.sum(res ** 2, axis=1)))))


def stations_of(table: PoseTable) -> list[str]:
    return table.station if table.station is not None else ["(all)"] * table.n


def locate(pred: np.ndarray, table: PoseTable, rows: np.ndarray | None = None) -> dict[str, Location]:
    """One :class:`Location` per station from the rows ``rows`` (default: all) of ``table``."""
    if table.points_mm is None:
        raise RobocalError(f"{table.source}: columns x, y, z (measured points) are needed to locate")
    st = np.array(stations_of(table))
    use = np.ones(table.n, bool) if rows is None else rows
    out = {}
    for s in dict.fromkeys(st):
        m = (st == s) & use
        out[str(s)] = fit_location(str(s), pred[m], table.points_mm[m])
    return out


def summary(res: np.ndarray) -> dict:
    """Mean, RMS, max and 95th percentile of residual lengths (mm): :func:`calib.accuracy.error_stats`."""
    return error_stats(np.linalg.norm(np.asarray(res, float).reshape(-1, 3), axis=1))


def breakdown(res: np.ndarray, table: PoseTable) -> dict[str, dict[str, dict]]:
    """Summary per label of every grouping column present (station, target, then the file's text columns)."""
    out = {}
    for name in ["station", "target", *table.columns]:
        labels = table.groups(name)
        if labels is None:
            continue
        lab = np.array(labels)
        groups = list(dict.fromkeys(labels))
        if len(groups) > 50:                 # a per-row column (a time stamp, an id) is no grouping
            continue
        out[name] = {g: summary(res[lab == g]) for g in groups}
    return out


def evaluate_table(model: MeasurementModel, theta: np.ndarray, table: PoseTable, with_locate: bool = False,
                   im=None) -> dict:
    """Residuals of the ``test`` rows (all rows without a split), optionally after re-stationing each station.

    With ``im`` (:class:`calib.compensate.IdentifiedModel` of a file that carries them): ``before`` (the located
    nominal model the identification fitted beside the calibrated one) and ``after`` (:func:`calib.accuracy.
    error_stats`), and the honesty of the predicted sigmas (``uncertainty``, :mod:`calib.heldout`)."""
    if table.points_mm is None:
        raise RobocalError(f"{table.source}: columns x, y, z (measured points) are needed to evaluate")
    pred = predict_rows(model, theta, table, new_stations=with_locate)
    axes = ori.axis_points(model, theta, table, new_stations=with_locate)
    test = table.split_mask("test")
    doc: dict = {"source": table.source, "rows": "test" if table.split is not None else "all"}
    locs = _locations(pred, table, test) if with_locate else {}
    if with_locate:
        pred = _restation(pred, table, locs)
        if axes is not None:
            axes = tuple(_restation(a, table, locs) for a in axes)
        doc["stations"] = [loc.as_dict() for loc in locs.values()]
    res = table.points_mm[test] - pred[test]
    doc.update(summary(res))
    doc["by"] = breakdown(res, table.subset(test))
    if axes is not None:                      # 6-D rows: the frame's error too, as a geodesic angle
        err = ori.geodesic_deg(ori.rotations(table.orientation_rad[test]),
                               ori.frames_from_points(*(a[test] for a in axes)))
        doc["orientation"] = {**ori.summary_deg(err), "convention": ori.CONVENTION}
    if im is not None and im.before_theta() is not None:
        doc.update(_before_after(im, table, test, res, locs, with_locate))
    return doc


def _locations(pred: np.ndarray, table: PoseTable, test: np.ndarray) -> dict[str, Location]:
    """Each station's transform from its fit rows (3 or more; else its rows)."""
    fit = table.split_mask("fit") if table.split is not None else np.ones(table.n, bool)
    st = np.array(stations_of(table))
    locs = {}
    for s in dict.fromkeys(st):
        own_fit = (st == s) & fit & (~test if table.split is not None else True)
        rows = own_fit if own_fit.sum() >= 3 else (st == s)
        locs[str(s)] = fit_location(str(s), pred[rows], table.points_mm[rows])
    return locs


def _restation(pred: np.ndarray, table: PoseTable, locs: dict[str, Location]) -> np.ndarray:
    st = np.array(stations_of(table))
    out = pred.copy()
    for s, loc in locs.items():
        m = st == s
        out[m] = loc.apply(pred[m])
    return out


def _before_after(im, table: PoseTable, test: np.ndarray, res: np.ndarray, locs: dict, with_locate: bool) -> dict:
    """``before``/``after`` on the rows evaluated (the located nominal model re-stationed the same way when
    ``with_locate``), and the predicted sigmas' honesty (parameter covariance plus the fit's noise)."""
    model = im.model
    before = predict_rows(model, im.before_theta(), table, new_stations=with_locate)
    if with_locate:
        before = _restation(before, table, _locations(before, table, test))
    sub = table.subset(test)
    ev = model.evaluate(sub.q_rad, context_of(model, sub, new_stations=with_locate), im.theta, jacobian=True)
    cov = np.einsum("nip,pq,njq->nij", ev.jacobian, im.cov, ev.jacobian)
    noise = im.prediction_noise or {}
    rows_cov = point_covariance(sub)
    if rows_cov is None:
        rows_cov = np.broadcast_to(np.eye(3) * float(noise.get("sigma_mm", 0.0)) ** 2, (sub.n, 3, 3))
    cov = cov + float(noise.get("scale", 1.0)) * rows_cov
    if with_locate:
        st = np.array(stations_of(sub))
        for s, loc in locs.items():
            m = st == s
            cov[m] = loc.R @ cov[m] @ loc.R.T
    protocol = ("the file's test rows" if table.split is not None else
                "every row of the file (held out when the model was not fitted to them)")
    return HeldOut(table.points_mm[test] - before[test], res, cov, protocol,
                   ori.orientation_errors_deg(model, im.before_theta(), sub),
                   ori.orientation_errors_deg(model, im.theta, sub)).as_dict()


def split_metrics(model: MeasurementModel, theta: np.ndarray, table: PoseTable) -> dict:
    """``fit_rms_mm``, ``test_rms_mm``, ``test_max_mm``, ``n_fit``, ``n_test`` of an identification (data with a
    split)."""
    pred = predict_rows(model, theta, table)
    res = table.points_mm - pred
    fit, test = table.split_mask("fit"), table.split_mask("test")
    f, t = summary(res[fit]), summary(res[test])
    return {"fit_rms_mm": f["rms_mm"], "test_rms_mm": t["rms_mm"], "test_max_mm": t["max_mm"],
            "n_fit": int(fit.sum()), "n_test": int(test.sum())}


def fit_rows(table: PoseTable, robot):
    """The rows an identification fits (``fit`` rows when the data has a split), the robot whose tool points are the
    targets those rows measure (the reference first) and the offset effects of the other targets (fitted jointly)."""
    fit = table.subset(table.split_mask("fit")) if table.split is not None else table
    if fit.n == 0:
        raise RobocalError(f"{table.source}: no fit rows (column split)")
    extra = station_effects(station_names(table))
    if fit.target is None:
        return fit, robot, extra
    robot, targets = with_targets(robot, list(dict.fromkeys(table.target)))
    return fit, robot, targets + extra


def data_rows(measured: PoseTable, fitted: PoseTable) -> tuple[list[int] | None, list[str] | None]:
    """The file's numbering of each fitted row (a split or orientation points make the fitted rows differ from the
    file's): its 1-based data row in ``measured`` (by source line; None when the rows carry no lines) and its pose id
    (None without a pose column) -- how outlier reports name poses."""
    ids = fitted.pose_id or None
    if not measured.line or len(fitted.line) != fitted.n:
        return None, ids
    row_of = {ln: k + 1 for k, ln in enumerate(dict.fromkeys(measured.line))}     # several targets: one row
    return [row_of.get(ln, i + 1) for i, ln in enumerate(fitted.line)], ids


def station_names(table: PoseTable) -> list[str]:
    """The instrument set-ups of a table by name, the reference (station 0) first: the sorted ``station`` labels
    (``[]`` without a station column).  A model identified from the table keeps them
    (:attr:`calib.model.MeasurementModel.stations`), so later data is matched to them by name."""
    return station_index(table.station, table.n)[1]


def station_start(model: MeasurementModel, table: PoseTable) -> np.ndarray:
    """Start parameters for several stations: each station's base by a rigid fit of the nominal chain to its rows;
    the first station's is the chain's base, the others' offsets are their differences from it."""
    th = model.nominal.copy()
    th[:6] = 0.0
    ctx = context_of(model, table)
    st = ctx.station.copy()
    ctx.station[:] = 0
    pred = model.points(table.q_rad, ctx, th)
    bases = {}
    for k in np.unique(st):
        loc = fit_location(str(k), pred[st == k], table.points_mm[st == k])
        roll, pitch, yaw = rpy_from_matrix(loc.R)
        bases[int(k)] = np.array([*loc.t_mm, yaw, pitch, roll])
    th[:6] = bases[0]
    for e, sl in zip(model.effects, model.effect_slices):
        if isinstance(e, StationOffset) and e.station in bases:
            d = bases[e.station] - bases[0]
            d[3:] = wrap_angle(d[3:])
            th[sl] = d
    # Chapter 6's linear step (eq 6.6) for the chain's translations, as identify's own start does for one station
    from .identify import PointObservations, linear_translations
    obs = PointObservations(table.q_rad, table.points_mm, point_covariance(table), ctx=context_of(model, table))
    trans = [n for n in model.kin.names if n.endswith("_mm") and not n.startswith("base.")]
    th[: model.n_geometric] = linear_translations(model, obs, th[: model.P], trans)[: model.n_geometric]
    return th
