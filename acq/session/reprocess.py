"""Offline reprocessing: the whole calibration rerun from a saved session with today's code, raw data read-only.

Pipeline (thesis Chapter 4, then Chapter 6), each stage from the *stored raw readings* only:

1. ruler -> L, gamma1, gamma2 (+ B's height; both faces: collimation and index) by :func:`ruler_lsq`;
2. every sighted target -> a point: face-I/II mean per station, least-squares intersection with the ruler's stations;
3. sweeps -> joint axes (:func:`fit_axis`) -> DH parameters (:func:`dh_estimate`);
4. pose set -> identification of the geometric parameters (:func:`calib.identify.identify`), joint readings from the
   recorded encoder counts;
5. transmission error (joint angle from A1, A2 about the swept axis vs the encoder) -> harmonic fit;
6. joint compliance (deflection vs torque, loading and unloading) -> two-slope fit;
7. link compliance (dial gauges) -> EI;  8. coupling (encoder counts) -> sigma_jk.

Output: a dict with ``estimates`` (name, value, error 1 sigma, unit, truth), per-procedure data for the report's
figures, and the identified robot description.  ``truth`` is filled only for sessions recorded from emulated
instruments (the twin of the session's scenario and seed).  Stages that fail say why in ``problems`` and the others
still run.
"""
from __future__ import annotations

import sqlite3
import time
from dataclasses import dataclass, field

import numpy as np

from calib.errors import RobocalError
from calib.provenance import provenance
from calib.units import ARCSEC, DEG, G0_M_S2

from .setup_file import setup_from_text
from .store import StoreError, code_version, connect_readonly, from_npy, json_column


@dataclass
class SessionData:
    path: str
    session: dict
    plan: dict
    setup: dict
    steps: list[dict]                               # accepted steps, each with readings, chunks, inputs
    devices: list[dict] = field(default_factory=list)


def _rows(conn, sql, args=()):
    cur = conn.execute(sql, args)
    cols = [d[0] for d in cur.description]
    return [dict(zip(cols, r)) for r in cur.fetchall()]


def load_session(path: str) -> SessionData:
    """Every accepted step with the readings of its accepted (last) attempt; opened read-only."""
    conn = connect_readonly(path)
    try:
        return _load(conn, path)
    except sqlite3.DatabaseError as exc:
        raise StoreError(f"{path}: damaged database ({exc})") from None
    finally:
        conn.close()


def _load(conn, path: str) -> SessionData:
    """The rows of :func:`load_session`, each JSON column and array blob checked as it is read."""
    sess = _rows(conn, "SELECT * FROM session ORDER BY session_id LIMIT 1")
    if not sess:
        raise RobocalError(f"{path}: holds no session")
    s = sess[0]
    steps = _rows(conn, "SELECT * FROM step WHERE session_id=? AND status='accepted' ORDER BY seq",
                  (s["session_id"],))
    for st in steps:
        a = st["attempts"]
        st["spec"] = json_column(st["spec_json"], f"{path}: step {st['key']!r}: spec_json")
        st["readings"] = _rows(conn, "SELECT station, target, face, repeat, hz_rad, v_rad FROM reading "
                                     "WHERE step_id=? AND attempt=? ORDER BY reading_id", (st["step_id"], a))
        st["inputs"] = {r["name"]: r["value"] for r in _rows(
            conn, "SELECT name, value FROM operator_input WHERE step_id=? AND attempt=? ORDER BY input_id",
            (st["step_id"], a))}
        ch = _rows(conn, "SELECT counts FROM encoder_chunk WHERE step_id=? AND attempt=? ORDER BY chunk_id",
                   (st["step_id"], a))
        st["counts"] = _counts(ch, f"{path}: step {st['key']!r}: encoder counts")
    devices = _rows(conn, "SELECT role, driver, url, identity_json FROM device")
    return SessionData(path, s, json_column(s["plan_json"], f"{path}: session plan_json"),
                       setup_from_text(s["setup_json"], f"{path}: session setup_json"), steps, devices)


def _counts(chunks: list[dict], where: str) -> np.ndarray | None:
    """The encoder counts of a step's chunks, one (samples, joints) array; damaged blobs are one line."""
    if not chunks:
        return None
    arrays = [from_npy(c["counts"], where) for c in chunks]
    if any(a.ndim != 2 or a.shape[1] != arrays[0].shape[1] for a in arrays):
        raise StoreError(f"{where}: damaged array data (chunks of different shapes)")
    return np.concatenate(arrays)


class _Est:
    """Collects estimates with their truths."""

    def __init__(self, truth: dict | None):
        self.truth = truth
        self.items: list[dict] = []
        self.bounds: list[dict] = []

    def add(self, name: str, value: float, error: float, unit: str, truth_key: str | None = None,
            truth_value: float | None = None, held: bool = False, **extra):
        """One estimate.  ``held``: not estimated -- kept at its design value because the data cannot determine it
        (its ``truth`` is shown for information; comparing it with ``value`` says nothing about the estimation)."""
        t = None
        if self.truth is not None:
            if truth_value is not None:
                t = float(truth_value)
            elif truth_key is not None and truth_key in self.truth:
                t = float(self.truth[truth_key])
        self.items.append({"name": name, "value": float(value), "error": float(error), "unit": unit, "truth": t,
                           "held": bool(held), **extra})

    def add_bound(self, name: str, value: float, unit: str, side: str, confidence: float,
                  truth_value: float | None = None, **extra):
        """A one-sided bound instead of an estimate (the data show the quantity is beyond what they can resolve):
        kept apart from ``items`` (``bounds`` in the results), since it has no 1-sigma error to compare with."""
        t = None if self.truth is None or truth_value is None or not np.isfinite(truth_value) else float(truth_value)
        self.bounds.append({"name": name, "value": float(value), "unit": unit, "side": side,
                            "confidence": float(confidence), "truth": t, **extra})

    def add_set(self, prefix: str, es, truth_map: dict | None = None, only=None):
        """Every estimate of ``es`` (or those named in ``only``) as ``prefix + name``.  One that is another estimate
        of the set under a second name (:meth:`calib.uncertainty.EstimateSet.same_as`) says so in ``same_as`` (and
        ``same_as_sign``: -1 when the two parametrisations have opposite signs), so a count of estimates takes it
        once."""
        same = es.same_as()
        for e in es.estimates():
            if only is not None and e.name not in only:
                continue
            tv = (truth_map or {}).get(e.name)
            extra = {}
            if e.name in same and (only is None or same[e.name][0] in only):
                extra = {"same_as": f"{prefix}{same[e.name][0]}", "same_as_sign": same[e.name][1]}
            self.add(f"{prefix}{e.name}", e.value, e.error, e.unit, truth_value=tv, **extra)


def _by_joint(steps) -> dict[int, list]:
    """A procedure's steps grouped by the joint they exercise (``spec.meta.joint``), in the order recorded."""
    out: dict[int, list] = {}
    for st in steps:
        out.setdefault(st["spec"]["meta"]["joint"], []).append(st)
    return out


def _twin_for(data: SessionData):
    meta = json_column(data.session.get("metadata_json") or "{}", f"{data.path}: session metadata_json")
    if not meta.get("emulated"):
        return None
    from calib.twin import Twin, load_scenario
    return Twin(load_scenario(meta.get("scenario_path") or None), seed=meta.get("seed", 0))


def reprocess(path: str, n_mc: int = 0, progress=None) -> dict:
    """Rerun every stage; returns the results document (see the module docstring)."""
    from calib.names import joint_label
    t0 = time.perf_counter()
    data = load_session(path)
    twin = _twin_for(data)
    truth = twin.true_parameters() if twin is not None else None
    est = _Est(truth)
    from .setup import setup_robot
    robot = setup_robot(data.setup)
    problems: list[str] = []
    details: list[str] = []          # the technical cause of a failed stage: JSON only, never the terminal or report
    figs: dict = {}
    by_proc: dict[str, list[dict]] = {}
    for st in data.steps:
        by_proc.setdefault(st["procedure"], []).append(st)
    sigma = data.setup["stations"].get("sigma_arcsec", 3.0) * ARCSEC
    step = (lambda name, f: progress(name, f)) if progress else (lambda name, f: None)

    # 1. ruler ----------------------------------------------------------------------------------------------------
    stations = None
    try:
        stations = _ruler(by_proc.get("ruler", []), data.setup, sigma, est, twin, figs)
    except (RobocalError, KeyError, ValueError, IndexError) as exc:
        problems.append(_worded("ruler", exc, details))
    if stations is None:
        from calib.estimators.points import StationFit
        from .setup import setup_stations
        stations = StationFit.exact(setup_stations(data.setup))
        problems.append("ruler: no estimate; points use the setup's stations")
    step("ruler", 0.1)
    located: dict[int, dict] = {}

    def points(st):
        """Targets of a step with covariances that carry the ruler fit's uncertainty (every step located in one
        batch on the first call)."""
        from calib.estimators.points import locate_targets
        if not located:
            rows = [{**r, "target": f"{i}/{r['target']}"} for i, s in enumerate(data.steps) for r in s["readings"]]
            located[-1] = {}
            for key, tp in locate_targets(rows, stations).items():
                i, tg = key.split("/", 1)
                located.setdefault(id(data.steps[int(i)]), {})[tg] = tp
        return located.get(id(st), {})
    points.station_fit = stations

    # 3. sweeps -> axes -> DH ---------------------------------------------------------------------------------------
    axes = {}
    try:
        axes = _sweeps(by_proc.get("sweep", []), points, robot, data.setup, est, truth, figs, n_mc)
    except (RobocalError, KeyError, ValueError, IndexError) as exc:
        problems.append(_worded("sweeps", exc, details))
    step("sweeps", 0.3)
    # 5-6 before the pose set: their running errors enter its model (priors on the effects) -------------------------
    running: dict = {}
    try:
        running["transmission"] = _transmission(by_proc.get("transmission", []), points, robot, axes, est, twin,
                                                figs, n_mc)
    except (RobocalError, KeyError, ValueError, IndexError) as exc:
        problems.append(_worded("transmission", exc, details))
    try:
        running["compliance"] = _compliance(by_proc.get("compliance", []), points, robot, axes, est, twin, figs,
                                            n_mc, data.setup, problems)
    except (RobocalError, KeyError, ValueError, IndexError) as exc:
        problems.append(_worded("compliance", exc, details))
    step("running errors", 0.45)
    # 4. pose set ---------------------------------------------------------------------------------------------------
    ident_doc = None
    try:
        ident_doc = _poses(by_proc.get("poses", []), points, robot, data.setup, est, twin, figs, running, problems,
                           by_proc.get("coupling", []))
    except (RobocalError, KeyError, ValueError, IndexError) as exc:
        problems.append(_worded("poses", exc, details))
    step("poses", 0.8)
    # 7-8 ---------------------------------------------------------------------------------------------------------
    try:
        _link(by_proc.get("link_compliance", []), data.setup, est, twin, figs, n_mc)
    except (RobocalError, KeyError, ValueError, IndexError) as exc:
        problems.append(_worded("link compliance", exc, details))
    try:
        _coupling(by_proc.get("coupling", []), robot, est, twin, figs, n_mc)
    except (RobocalError, KeyError, ValueError, IndexError) as exc:
        problems.append(_worded("coupling", exc, details))
    try:
        _resolution(by_proc.get("encoder_resolution", []), points, robot, est, twin, figs)
    except (RobocalError, KeyError, ValueError, IndexError) as exc:
        problems.append(_worded("encoder resolution", exc, details))
    step("done", 1.0)
    problems += figs.pop("problems", [])          # what a stage could not do for part of its data
    return {
        "session": {"guid": data.session["guid"], "title": data.session["title"], "path": path,
                    "exit_status": data.session["exit_status"], "steps_accepted": len(data.steps),
                    "procedures": {name: len(sts) for name, sts in by_proc.items()}},
        "provenance": {**provenance(data.setup.get("robot") or None, twin.scenario.source if twin else None),
                       "code_version": code_version(), "reprocessed_unix_s": time.time(), "input_session":
                       data.session["guid"], "n_mc": n_mc, "elapsed_s": time.perf_counter() - t0},
        "estimates": est.items,
        "bounds": est.bounds,
        "accuracy": {k: v for k, v in figs.get("accuracy", {}).items() if not k.endswith(("_err_mm", "_index"))}
        or None,
        "problems": problems,
        "problem_details": details,
        "robot": ident_doc,
        "joint_labels": [joint_label(robot, j) for j in range(1, robot.n + 1)],     # how reports name the joints
        "figures": figs,
    }


def _worded(stage: str, exc: Exception, details: list[str]) -> str:
    """A failed stage in words for the operator: robocal's own errors already say what is wrong; anything else (a
    computation that failed on these readings) is said plainly, its technical cause kept in ``details`` (the JSON's
    ``problem_details``) for whoever maintains robocal, never shown as exception text."""
    if isinstance(exc, RobocalError):
        return f"{stage}: {exc}"
    details.append(f"{stage}: {type(exc).__name__}: {exc}")
    return (f"{stage}: the recorded readings of this stage could not be reduced to estimates (the computation failed "
            f"on them); check that every step of it was recorded, repeat its steps, and send the session file with "
            f"the results JSON to the maintainers if it persists")


# -- stages ------------------------------------------------------------------------------------------------------
def _ruler(steps, setup, sigma, est, twin, figs):
    """The same ruler fit the runner uses live (:mod:`acq.session.stations`), recorded with its estimates."""
    from .setup import station_names
    from .stations import fit_ruler, ruler_rows, ruler_station_fit
    if not steps:
        return None
    cfg = {**setup, "stations": {**setup["stations"], "sigma_arcsec": sigma / ARCSEC}}
    res, stations = fit_ruler(ruler_rows(steps, station_names(setup)), cfg)
    tv = {}
    if twin is not None:
        A, B = twin.stations
        tv = {"L_mm": B.x_mm - A.x_mm, "gamma1_rad": -A.yaw_rad, "gamma2_rad": B.yaw_rad - np.pi,
              "hB_mm": B.z_mm - A.z_mm}
    est.add_set("ruler.", res, tv, only=("L_mm", "gamma1_rad", "gamma2_rad", "hB_mm"))
    L, g1, g2 = (res[n].value for n in ("L_mm", "gamma1_rad", "gamma2_rad"))
    figs["ruler"] = {"L_mm": L, "gamma1_deg": g1 / DEG, "gamma2_deg": g2 / DEG,
                     "residual_arcsec": (np.asarray(res.extras.get("residual", [])) / ARCSEC).tolist()}
    return ruler_station_fit(res, stations)


def _block(pts, points):
    """Joint covariance of located targets (the stations' common term included)."""
    from calib.estimators.points import points_covariance
    return points_covariance(pts, points.station_fit)


def _sweeps(steps, points, robot, setup, est, truth, figs, n_mc):
    from calib.estimators.axes import fit_axis
    from calib.estimators.dh import dh_estimate
    from calib.kinematics import Kinematics
    if not steps:
        return {}
    p_steps = [st for st in steps if st["spec"]["meta"].get("point") == "P"]   # point P (d3), not a sweep
    by_joint = _by_joint([st for st in steps if "joint" in st["spec"]["meta"]])
    axes = {}
    figs["sweeps"] = {}
    for j, sts in sorted(by_joint.items()):
        sts.sort(key=lambda s: s["spec"]["meta"]["index"])
        pts = [points(s)["P"] for s in sts]
        P = np.array([p[0] for p in pts])
        U = _block(pts, points)
        res = fit_axis(P, U, n_mc=n_mc, joint=f"j{j}")
        axes[j] = res
        v = res.value
        figs["sweeps"][j] = {"points_mm": P.tolist(), "centre_mm": v[:3].tolist(), "normal": v[3:6].tolist(),
                             "radius_mm": float(v[6]),
                             "residual_mm": np.asarray(res.extras.get("residual_mm", [])).ravel().tolist()}
    if len(axes) < robot.n:
        return axes
    kin = Kinematics(robot)
    p = kin.nominal.copy()
    for k, val in zip(("x_mm", "y_mm", "z_mm"), setup["base_xyz_mm"]):
        p[kin.index[f"base.{k}"]] = val
    yaw, pitch, roll = (np.asarray(setup.get("base_rpy_deg", [0, 0, 0]), float) * DEG)[::-1]
    p[kin.index["base.yaw_rad"]], p[kin.index["base.pitch_rad"]], p[kin.index["base.roll_rad"]] = yaw, pitch, roll
    q0 = _reference_pose(steps, setup)
    fn = kin.forward(q0[None], p)
    vals, covs = [], []
    for j in range(1, robot.n + 1):
        a = axes[j]
        vals.append(a.value[:6])
        covs.append(a.cov[:6, :6])
    V = np.concatenate(vals)
    C = np.zeros((6 * robot.n, 6 * robot.n))
    for i, c in enumerate(covs):
        C[6 * i:6 * i + 6, 6 * i:6 * i + 6] = c
    dh = dh_estimate(V, C, q0, fn.frame_R[0, 0], fn.frame_t[0, 0], fn.frame_R[0, 1:-1, :, 0], robot.hayati[:-1],
                     robot.d_mm[:-1], alpha_ref=robot.alpha_rad[:-1], n_mc=n_mc)
    tv = {n: truth[n] for n in dh.names if truth is not None and n in truth}
    tv.update(_base_gauge_truth(truth, setup, fn.frame_R[0, 0], tv))
    for k in np.flatnonzero(robot.hayati[:-1]):
        # d of a Hayati link is held at its design value; the next link's d (its axis is parallel) takes the rest
        held, nxt = f"j{k + 1}.d_mm", f"j{k + 2}.d_mm"
        if truth is not None and held in truth and nxt in tv:
            tv[nxt] = truth[nxt] + np.cos(robot.alpha_rad[k]) * (truth[held] - robot.d_mm[k])
    est.add_set("dh.", dh, tv)
    nominal = dict(zip(kin.names, kin.nominal))
    figs["dh"] = [{"name": n, "value": float(dh[n].value), "error": float(dh[n].error),
                   "nominal": float(nominal.get(n, np.nan)), "truth": tv.get(n)} for n in dh.names]
    try:
        _misalignment(axes, kin, p, q0, robot, est, truth, figs, n_mc)
    except (RobocalError, KeyError, ValueError) as exc:             # the axes and DH stand without it
        figs.setdefault("problems", []).append(f"misalignment: {exc}")
    try:
        _compensation_scheme(axes, p_steps, points, kin, p, q0, robot, setup, est, truth, figs, n_mc)
    except (RobocalError, KeyError, ValueError, np.linalg.LinAlgError) as exc:
        figs.setdefault("problems", []).append(f"compensation scheme: {exc}")
    return axes


def _compensation_scheme(axes, p_steps, points, kin, p_design, q0, robot, setup, est, truth, figs, n_mc):
    """The thesis's own reduction (eqs 4.3.12-15): the joint centres compensated into S_fj, then a1, a2, d1, d2, and
    d3 from point P and L_p when P was sighted.  Only for a six-axis Puma-like arm (the formulas are the Puma's).
    Truth: the same reduction of the twin's exact axes and P (what noise-free sightings give), and for d3 the
    twin's flange offset itself."""
    from calib.estimators.misalignment import thesis_route
    if robot.n != 6:
        return
    design = kin.forward(q0[None], p_design)
    zd = np.array([design.frame_R[0, j][:, 2] for j in range(6)])
    xf = np.array([design.frame_R[0, j + 1][:, 0] for j in range(6)])
    V = np.concatenate([axes[j].value[:6] for j in range(1, 7)])
    C = np.zeros((36, 36))
    for j in range(6):
        C[6 * j:6 * j + 6, 6 * j:6 * j + 6] = axes[j + 1].cov[:6, :6]
    P = Pc = lp = None
    if p_steps:
        pts = [points(s)["P"] for s in p_steps]
        Pc = _block(pts, points)
        m = len(pts)
        W = np.kron(np.ones((1, m)), np.eye(3)) / m                          # mean of the repeats
        P, Pc = W @ np.concatenate([t[0] for t in pts]), W @ Pc @ W.T
        lp = p_steps[0]["spec"]["meta"].get("L_p_mm")
        if lp is None:                                   # an imported step: L_p from the set-up
            from .setup import point_p
            pp = point_p(setup)
            lp = None if pp is None else pp[2]
        if lp is None:
            P = Pc = None
            figs.setdefault("problems", []).append("compensation scheme: point P sighted but the set-up gives no "
                                                   "L_p (point_p.L_p_mm): d3 not computed")
    base_R = design.frame_R[0, 0]
    res = thesis_route(V, C, zd, xf, P, Pc, lp, base_R, n_mc=n_mc)
    tv = {}
    if truth is not None:
        tv = _compensation_truth(kin, p_design, q0, truth, setup, zd, xf, lp, base_R, res.names)
    est.add_set("comp.", res, tv)
    figs["compensation"] = [{"name": nm, "value": float(res[nm].value), "error": float(res[nm].error),
                             "truth": tv.get(nm)} for nm in res.names]


def _compensation_truth(kin, p_design, q0, truth, setup, zd, xf, lp, base_R, names) -> dict:
    """The thesis route on the twin's exact geometry at the reference pose: each sweep target's foot on its true
    axis as the centre, the true axis directions, P where the twin puts it."""
    from calib.estimators.dh import puma_formulas
    from calib.estimators.misalignment import compensated_puma_inputs
    from .procedures import sweep_target
    from .setup import point_p
    pt = np.array([truth.get(nm, v) for nm, v in zip(kin.names, p_design)])
    fp = kin.forward(q0[None], pt)
    n_links = kin.robot.n
    ax = []
    for j in range(6):
        z, o = fp.joint_axis[0, j], fp.joint_origin[0, j]
        tg = sweep_target(setup, j + 1)
        x = kin.point_on(fp, [n_links if tg.link is None else tg.link], np.asarray(tg.tool_mm, float))[0, 0]
        ax.append(np.concatenate([o + ((x - o) @ z) * z, z]))
    pp = point_p(setup)
    P = kin.point_on(fp, [pp[0]], np.asarray(pp[1]))[0, 0] if pp is not None else np.zeros(3)
    vals = puma_formulas(compensated_puma_inputs(np.array(ax), zd, xf, P, lp or 0.0, base_R))
    out = dict(zip(names, vals))
    if "d3_mm" in out and f"j{n_links}.d_mm" in truth:
        out["d3_mm"] = float(truth[f"j{n_links}.d_mm"])
    return out


def _base_gauge_truth(truth, setup, R0, tv: dict) -> dict:
    """The truth of the first link's d and zero offset in the frame the sweeps measure them in: frame 0 where the
    set-up puts the base (a tape gives it to the millimetre), not where the twin has it.  Why: the foot of joint 1's
    common normal is measured from the set-up's origin along z0, and its zero from the set-up's yaw, so a base 0.1
    mm lower than written reads as d1 0.1 mm larger -- a gauge, not an estimation error (as the pose set's held
    parameters, ``_gauge_truth``)."""
    if truth is None or "base.z_mm" not in truth:
        return {}
    out = {}
    o_true = np.array([truth[f"base.{k}_mm"] for k in "xyz"])
    o_set = np.asarray(setup.get("base_xyz_mm", o_true), float)
    if "j1.d_mm" in tv:
        out["j1.d_mm"] = tv["j1.d_mm"] + float((o_true - o_set) @ R0[:, 2])
    if "j1.theta_offset_rad" in tv and "base.yaw_rad" in truth:
        yaw_set = float(np.asarray(setup.get("base_rpy_deg", [0.0, 0.0, 0.0]), float)[2]) * DEG
        out["j1.theta_offset_rad"] = tv["j1.theta_offset_rad"] + truth["base.yaw_rad"] - yaw_set
    return out


def _misalignment(axes, kin, p_design, q0, robot, est, truth, figs, n_mc):
    """Fig 5.10's misalignment rows (eqs 4.3.10-4.3.13): each measured axis against its design direction at the
    reference pose, with errors from the axes' covariances; truth from the twin's own frames at that pose."""
    from calib.estimators.misalignment import ROW, misalignment_table
    n = robot.n
    design = kin.forward(q0[None], p_design)
    zd = np.array([design.frame_R[0, j][:, 2] for j in range(n)])
    xf = np.array([design.frame_R[0, j + 1][:, 0] for j in range(n)])
    N = np.array([axes[j + 1].value[3:6] for j in range(n)])
    U = np.zeros((3 * n, 3 * n))
    for j in range(n):
        U[3 * j:3 * j + 3, 3 * j:3 * j + 3] = axes[j + 1].cov[3:6, 3:6]
    res = misalignment_table(N, U, zd, xf, n_mc=n_mc)
    tv = {}
    if truth is not None:
        from calib.estimators.dh import misalignments
        pt = np.array([truth.get(nm, v) for nm, v in zip(kin.names, p_design)])
        tr = kin.forward(q0[None], pt)
        zt = np.array([tr.frame_R[0, j][:, 2] for j in range(n)])
        full = [f"j{k + 1}.{r}" for k in range(n) for r in ROW]
        tv = {k: v for k, v in zip(full, misalignments(zt, zd, xf).ravel()) if k in res.names}
    est.add_set("misalign.", res, tv)
    figs["misalignment"] = [{"joint": j + 1, **{r.replace("_rad", "_deg"): float(res[f"j{j + 1}.{r}"].value) / DEG
                                                for r in ROW if f"j{j + 1}.{r}" in res.names},
                             "error_deg": float(max(res[k].error for k in res.names if k.startswith(f"j{j + 1}.")))
                             / DEG} for j in range(n)]


def _reference_pose(sweep_steps, setup) -> np.ndarray:
    """The pose the joints were swept about (rad): the set-up's ``reference_pose_deg`` when given, else from the
    session's own sweep steps -- every sweep holds the other joints at it and centres its own joint on it."""
    if setup.get("reference_pose_deg") is not None:
        return np.asarray(setup["reference_pose_deg"], float) * DEG
    return np.median(np.array([st["spec"]["pose_deg"] for st in sweep_steps], float), axis=0) * DEG


def _encoder_q(st, robot) -> np.ndarray | None:
    c = st.get("counts")
    if c is None or len(c) == 0:
        return None
    return robot.joint_from_counts(np.mean(c, 0))


def running_error_specs(setup: dict, running: dict, coupling_steps=()) -> list[str]:
    """The running errors the pose set's model carries, as effect specs (:func:`calib.effects.effect_from_text`).

    From the session, never from one robot: the set-up's ``running_errors`` list when it has one; otherwise the
    effects the session itself measured -- a transmission error at the order its run found for each joint of the
    transmission-error run, a joint compliance for each joint whose stiffness was determined, and a cross coupling
    for each pair of the coupling run.
    """
    if setup.get("running_errors") is not None:
        return [str(t) for t in setup["running_errors"]]
    specs = [f"transmission_error:{j}:{res['omega'].value:.4g}"
             for j, res in sorted((running.get("transmission") or {}).items())]
    specs += [f"joint_compliance:{j}" for j in sorted(running.get("compliance") or {})]
    pairs = sorted({(st["spec"]["meta"]["j"], st["spec"]["meta"]["k"]) for st in coupling_steps})
    specs += [f"cross_coupling:{k}:{j}" for j, k in pairs]
    return specs


def _pose_model(robot, running: dict, problems: list[str], specs=None):
    """The pose set's model: geometry plus the session's running errors (:func:`running_error_specs`), with priors
    on the effects from the session's own transmission-error and compliance runs.

    Why: the pose set is measured with the gears' transmission error, gravity bending the joints and the
    uncompensated wrist coupling all present; a geometry-only fit folds them into the geometry and misses the true
    parameters by tens of sigma.  The effects' values are identified with the geometry, held near what the dedicated
    procedures measured (priors with those procedures' errors), so a poorly measured stiffness cannot bias the fit.
    """
    from calib.effects import effect_from_text
    from calib.estimators.compliance import MAX_REL_ERROR_TWO_SLOPES
    from calib.model import MeasurementModel
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
            for name, v, sv in _harmonic_prior(res):
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


def _harmonic_prior(res) -> list[tuple[str, float, float]]:
    """The transmission-error run's first harmonic as the pose-set model's sine and cosine coefficients with their
    1-sigma: ``A sin(w q + phi) = A cos(phi) sin(w q) + A sin(phi) cos(w q)``, the amplitude's and the phase's errors
    (and their correlation) both propagated -- a phase known to 0.1 rad moves the coefficients by a tenth of A."""
    names = list(res.names)
    i, k = names.index("amplitude1_rad"), names.index("phase1_rad")
    (s1, c1), G = _sine_cosine(float(res.value[i]), float(res.value[k]))
    C = res.cov[np.ix_([i, k], [i, k])]
    sd = np.sqrt(np.maximum(np.diag(G @ C @ G.T), 1e-12))
    return [("s1_rad", s1, float(sd[0])), ("c1_rad", c1, float(sd[1]))]


def _sine_cosine(A: float, phi: float) -> tuple[tuple[float, float], np.ndarray]:
    """``A sin(w q + phi)`` as the model's sine and cosine coefficients ``(A cos phi, A sin phi)`` and their
    Jacobian with respect to ``(A, phi)`` (2x2): the one place the run's harmonic meets the model's."""
    c, s = np.cos(phi), np.sin(phi)
    return (A * c, A * s), np.array([[c, -A * s], [s, A * c]])


def _poses(steps, points, robot, setup, est, twin, figs, running=None, problems=None, coupling_steps=()):
    from calib.compensate import model_document
    from calib.identify import PointObservations, default_free, identify

    from .imported import imported_context, imported_point, one_target_one_station
    if not steps:
        return None
    problems = [] if problems is None else problems
    q, P, S, D, used = [], [], [], [], []
    for st in steps:
        pt = points(st).get("P") if st["readings"] else None
        if pt is None:
            pt = imported_point(st)                               # an imported pose CSV: its own sigmas
        if pt is None:
            continue
        qe = _encoder_q(st, robot)
        q.append(qe if qe is not None else np.asarray(st["spec"]["pose_deg"]) * DEG)
        P.append(pt[0])
        S.append(pt[1])
        D.append(getattr(pt, "d_station", None))
        used.append(st)
    if len(q) < 8:
        raise RobocalError(f"only {len(q)} poses with both sightings; identification needs more")
    one_target_one_station(used, "reprocess")
    specs = running_error_specs(setup, running or {}, coupling_steps)
    model, theta0, priors = _pose_model(robot, running or {}, problems, specs)
    q, P = np.array(q), np.array(P)
    obs = PointObservations(q, P, cov_mm2=np.array(S), ctx=imported_context(used, robot.n))
    # the dead zone needs loading and unloading, which a pose set has not: it stays out
    wanted = [n for n in default_free(model, effects=True) if not n.endswith("deadzone_rad")]
    ident = identify(model, obs, free=wanted, theta0=theta0, priors=priors)
    te_add, te_prior = _te_run_variance(robot, running or {}, specs, obs, ident, priors, problems)
    var = ident.sigma ** 2 + _station_variance(model, obs, D, ident, priors, points.station_fit, problems) + te_add
    sigma, floored = _floored_sigma(var, ident.sigma ** 2, te_prior)
    truth = twin.true_parameters() if twin is not None else None
    gauge = _gauge_truth(twin, model, ident, q) if twin is not None else {}
    compared = {}                  # the truth each estimate is compared with: the twin's, in the fit's gauge
    unknown = _held_away(model, ident, truth)
    for n in ident.free:
        i = ident.names.index(n)
        raw = None if truth is None else truth.get(n)
        extra = {}
        tv = None if n in unknown else gauge.get(n, raw)
        if tv is not None:
            compared[n] = tv
        if n in unknown and raw is not None:
            extra = {"truth_raw": float(raw), "note": unknown[n]}
        if raw is not None and tv is not None and abs(tv - raw) > 0.1 * sigma[i]:
            extra = {"truth_raw": float(raw), "note": "truth in the gauge of the held parameters (what perfect data "
                                                      "would give with them at their design values)"}
        if floored[i]:
            extra["note"] = "; ".join(filter(None, [extra.get("note"), FLOOR_NOTE]))
        est.add(f"ident.{n}", ident.theta[i], sigma[i], _unit(n), truth_value=tv, **extra)
    for n in wanted:
        if n in ident.free:
            continue
        why = [c.words(robot) for c in ident.identifiability.unidentifiable + ident.identifiability.weak
               if n in c.coefficients][:1]
        est.add(f"ident.{n}", ident.value(n), 0.0, _unit(n), truth_key=n, held=True,
                note="held at its design value, not estimated" + (f": {why[0]}" if why else "")
                     + "; its truth is not comparable with the value")
    pred = model.points(q, theta=ident.theta[:model.P])
    figs["poses"] = {"residual_mm": np.linalg.norm(P - pred, axis=1).tolist(),
                     "rms_mm": float(ident.residual_rms), "held": [n for n in wanted if n not in ident.free],
                     "points_mm": P.tolist(), "running_errors": list(specs)}
    _accuracy(model, obs, ident.free, theta0, priors, figs, problems)
    return _with_truth_notes(model_document(model, ident, compared if truth is not None else None), truth, gauge,
                             unknown)


def _with_truth_notes(doc: dict, raw: dict | None, gauge: dict, unknown: dict[str, str]) -> dict:
    """The identified model document's ``truth``s say what the estimates are compared with: for an estimated
    parameter the twin's value in the fit's gauge (as the ``ident.*`` estimates; the twin's own value as
    ``truth_raw`` where they differ), for a held one none -- its value is the design value by choice, not an
    estimate, and the twin's own value (``truth_raw``) is not comparable with it -- nor for an effect parameter whose
    companions are held away from the twin's (``unknown``, :func:`_held_away`).  Never a nominal value as truth."""
    if raw is None:
        return doc
    for p in doc["parameters"]:
        r = raw.get(p["name"])
        if not p["estimated"]:
            p["truth"] = None
            p["note"] = "held at its design value, not estimated: no truth to compare it with"
            if r is not None:
                p["truth_raw"] = float(r)
        elif p["name"] in unknown:
            p["note"] = unknown[p["name"]]
            if r is not None:
                p["truth_raw"] = float(r)
        elif r is not None and p["name"] in gauge and p["truth"] is not None and abs(p["truth"] - r) > 0:
            p["truth_raw"] = float(r)
            p["note"] = ("truth in the gauge of the held parameters (what perfect data would give with them at "
                         "their design values)")
    return doc


def _accuracy(model, obs, free, theta0, priors, figs, problems) -> None:
    """Before/after accuracy on held-out poses (:mod:`calib.accuracy`) into ``figs['accuracy']``; a pose set too
    small to split is said in ``problems``, not guessed."""
    from calib.accuracy import before_after
    try:
        acc = before_after(model, obs, free, theta0=theta0, priors=priors)
    except RobocalError as exc:
        problems.append(f"poses: accuracy before/after not computed: {exc}")
        return
    figs["accuracy"] = {**acc.as_dict(), "test_index": acc.test_index.tolist(),
                        "before_err_mm": acc.before_err_mm.tolist(), "after_err_mm": acc.after_err_mm.tolist()}


def _station_variance(model, obs, D, ident, priors, fit, problems: list[str] | None = None) -> np.ndarray:
    """What the stations' own uncertainty adds to each identified parameter's variance.

    Why: every pose point was intersected with the same ruler-fitted stations, so an error in L (a scale) or B's
    height moves all of them together and does not average down over the poses; the identification's covariance
    treats the points as independent.  Each station parameter is moved by its 1-sigma, the points follow through
    their sensitivities, and the identification is re-solved from its own estimate: ``G U_station G^T``.  A re-solve
    is a small step from a converged fit: no linear start and no second outlier search (the main fit flagged them and
    kept every pose), only the final least squares.  A re-solve that fails, or a free parameter it leaves undefined,
    is said in ``problems`` (the errors then leave that part of the stations' term out): never a silent zero."""
    from calib.identify import PointObservations, identify
    out = np.zeros(len(ident.theta))
    if not fit.cov.size or any(d is None for d in D):
        return out
    free = np.zeros(len(ident.theta), bool)
    free[[ident.names.index(n) for n in ident.free]] = True
    said = problems if problems is not None else []
    Dk = np.array(D)                                          # (N, 3, K)
    G = []
    for k, sd in enumerate(np.sqrt(np.diag(fit.cov))):
        moved = PointObservations(obs.q_rad, obs.points_mm + Dk[:, :, k] * sd, cov_mm2=obs.cov_mm2)
        try:
            g = identify(model, moved, free=list(ident.free), theta0=ident.theta, priors=priors, robust=False,
                         start=False)
        except RobocalError as exc:
            said.append(f"poses: the stations' uncertainty is left out of the errors (re-solve with station "
                        f"parameter {k} moved by 1 sigma failed: {exc})")
            return out
        with np.errstate(invalid="ignore"):
            gk = np.where(free, (g.theta - ident.theta) / sd, 0.0)    # held parameters (possibly at +-inf): 0
        bad = free & ~np.isfinite(gk)
        if bad.any():
            said.append(f"poses: the stations' uncertainty is left out of the errors of "
                        f"{', '.join(np.asarray(ident.names)[bad])} (station parameter {k}'s re-solve left them "
                        f"undefined)")
            gk[bad] = 0.0
        G.append(gk)
    G = np.stack(G, -1)
    return np.einsum("pk,kl,pl->p", G, fit.cov, G)


FLOOR_NOTE = ("error floored at the fit's own variance: the stations' and the transmission-error run's terms came "
              "out below it (numerical), never an error of 0")


def _floored_sigma(var: np.ndarray, fit_var: np.ndarray, prior_var: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Errors from the total variances ``var``, each floored at the fit's own variance -- ``fit_var`` (the
    identification's, reduced chi-square included) less the independent-prior terms ``prior_var`` that the
    transmission-error run's covariance replaces (the whole ``fit_var`` where that is not positive).  Why: the
    station and run terms added to it are positive semi-definite, so a total below the floor is rounding or a
    sensitivity gone wrong; a clip to 0 turned it into an error of 0, which the honesty check then skipped silently.
    Returns the errors and where the floor was hit (to be noted on the estimate)."""
    own = fit_var - prior_var
    floor = np.where(own > 0, own, fit_var)
    hit = ~(var >= floor)                       # NaN counts as hit
    return np.sqrt(np.where(hit, floor, var)), hit


def _te_run_variance(robot, running: dict, specs: list[str], obs, ident, priors,
                     problems: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """What the transmission-error run's order, and the correlation of its coefficients, add to each identified
    parameter's variance.

    Why: the pose set's model holds a joint's transmission-error order at the run's estimate and takes the run's sine
    and cosine coefficients as independent priors.  But the order is known only to its error (joint 4's 0.9 to about
    5 % over a 270 deg run), a different order moves the coefficients the pose set finds, and the run's order,
    amplitude and phase are correlated.  So the run's whole covariance of (order, sine, cosine) goes through the fit:
    ``J U J^T`` with the sensitivity to the order from refits with the order moved by a tenth of its error either
    way, and to the prior values from the priors' gain ``C P`` -- in place of the independent-prior term
    ``C P C`` the identification's covariance holds.  Left out, the pose set's joint-4 coefficients scattered
    1.15 times their errors over 40 seeded demo runs.

    Returns what to add to each variance (``J U J^T`` less the prior term it replaces) and that prior term alone,
    both in the identification's scale (its covariance is inflated by the reduced chi-square, so the prior term it
    holds is ``scale g^2 sd^2``).  A refit that fails, or gives a non-finite sensitivity of a free parameter, leaves
    that joint at the independent-prior term, with a line in ``problems`` -- never a sensitivity of 0."""
    from calib.identify import identify
    out, removed = np.zeros(len(ident.theta)), np.zeros(len(ident.theta))
    problems = [] if problems is None else problems
    free = np.isin(ident.names, list(ident.free))
    scale = max(1.0, float(ident.reduced_chi2))
    for j, res in sorted((running.get("transmission") or {}).items()):
        at = [i for i, t in enumerate(specs) if t.startswith(f"transmission_error:{j}:")]
        pri = [f"transmission_error.j{j}.{k}_rad" for k in ("s1", "c1")]
        if len(at) != 1 or not all(n in priors and n in ident.free for n in pri) or "omega" not in res.names:
            continue
        idx = [list(res.names).index(n) for n in ("omega", "amplitude1_rad", "phase1_rad")]
        G = np.eye(3)                                             # (order, s1, c1) from (order, A, phi)
        G[1:, 1:] = _sine_cosine(*(float(res.value[i]) for i in idx[1:]))[1]
        U = G @ res.cov[np.ix_(idx, idx)] @ G.T
        order = float(specs[at[0]].rsplit(":", 1)[1])
        h = 0.1 * float(np.sqrt(U[0, 0]))
        moved, written = [], []
        for sgn in (1.0, -1.0):
            sp = list(specs)
            sp[at[0]] = f"transmission_error:{j}:{order + sgn * h:.8g}"
            written.append(float(sp[at[0]].rsplit(":", 1)[1]))     # the order the refit used, as written
            model, _, _ = _pose_model(robot, running, [], sp)
            try:        # a small step from the converged fit, as in _station_variance: no linear start or outlier search
                moved.append(identify(model, obs, free=list(ident.free), theta0=ident.theta, priors=priors,
                                      robust=False, start=False).theta)
            except RobocalError:
                break
        step = written[0] - written[-1]
        with np.errstate(invalid="ignore", divide="ignore"):
            dw = (moved[0] - moved[-1]) / step if len(moved) == 2 and step > 0 else np.full(len(ident.theta), np.nan)
        if not np.all(np.isfinite(dw[free])):
            problems.append(f"poses: the refit with joint {j}'s transmission-error order moved failed: its "
                            f"coefficients' errors keep the independent-prior term (the order's error is not "
                            f"propagated)")
            continue
        dw = np.where(free, dw, 0.0)                  # held parameters are not estimated: no sensitivity to carry
        gain = [ident.cov[:, ident.names.index(n)] / (priors[n][1] ** 2 * scale) for n in pri]
        J = np.stack([dw, *gain], -1)
        prior_term = scale * sum(g * g * priors[n][1] ** 2 for g, n in zip(gain, pri))
        out += np.einsum("pk,kl,pl->p", J, U, J) - prior_term
        removed += prior_term
    return out, removed


def _unit(name: str) -> str:
    return "mm" if name.endswith("_mm") else ("rad" if name.endswith("_rad") else
                                               ("rad/N m" if name.endswith("_per_nm") else "1"))


def _gauge_truth(twin, model, ident, q) -> dict[str, float]:
    """The twin's geometry expressed in the identification's gauge: parameters the pose set cannot determine are held
    at their design values, and the free ones absorb their true deviations (the base yaw takes joint 1's zero
    offset, d3 takes d2 of the parallel pair ...).  Fitting the twin's own model, effects at their true values, to
    its noise-free points at the session's joint readings, with the same parameters held, gives the values a perfect
    estimator would return: the honest truth to compare the estimates with."""
    from calib.identify import PointObservations, identify
    tm = twin.model
    th = np.array(twin.theta, float)
    geo_free = [n for n in ident.free if n in tm.kin.index]
    for n in tm.kin.names:
        if n not in geo_free and n in model.kin.index:
            th[tm.index[n]] = ident.value(n)
    pts, _ = twin.true_points(q)
    try:
        g = identify(tm, PointObservations(q, pts, sigma_mm=0.01), free=geo_free, theta0=th, robust=False)
    except RobocalError:
        return {}
    return {n: g.value(n) for n in g.free}


def _held_away(model, ident, truth: dict | None) -> dict[str, str]:
    """Estimated effect parameters whose effect has a parameter held away from the twin's value (a joint compliance
    fitted with one slope, its breakpoint held at infinity, where the twin has two slopes and a breakpoint): the free
    one absorbs the difference, so no truth in the fit's gauge is known for it -- name -> why, in words."""
    if truth is None:
        return {}
    away: dict[str, list[str]] = {}
    for n in ident.names:
        if (n in model.index and n not in model.kin.index and n not in ident.free and n in truth
                and not np.isclose(truth[n], ident.value(n))):
            away.setdefault(n.rsplit(".", 1)[0], []).append(f"{n.rsplit('.', 1)[1]} held at {ident.value(n):.4g} "
                                                             f"(twin {truth[n]:.4g})")
    return {n: "no truth in the fit's gauge: its effect has " + ", ".join(away[n.rsplit(".", 1)[0]])
            for n in ident.free if n not in model.kin.index and n.rsplit(".", 1)[0] in away}


def _joint_angles(steps, points, axis_n, full: bool = False):
    """Angle turned about ``axis_n`` from the first step, per step, from A1 -> A2, and each one's 1-sigma
    (:func:`calib.estimators.transmission.joint_angles`); NaN where a step lacks A1 or A2.  ``full``: also the
    angles' covariance (the stations' errors are common to every step)."""
    from calib.estimators.transmission import joint_angles
    out, cov = np.full(len(steps), np.nan), np.full((len(steps), len(steps)), np.nan)
    ok = [i for i, st in enumerate(steps) if {"A1", "A2"} <= set(points(st))]
    if ok:
        pairs = [(points(steps[i])["A1"], points(steps[i])["A2"]) for i in ok]
        read = np.array([np.block([[a.cov_reading_mm2, np.zeros((3, 3))], [np.zeros((3, 3)), b.cov_reading_mm2]])
                         for a, b in pairs])
        D = np.array([np.concatenate([a.d_station, b.d_station]) for a, b in pairs])
        out[ok], cov[np.ix_(ok, ok)] = joint_angles(np.array([a.point_mm for a, _ in pairs]),
                                                    np.array([b.point_mm for _, b in pairs]), read, axis_n, D,
                                                    points.station_fit.cov)
    sig = np.sqrt(np.diag(cov))
    return (out, sig, cov) if full else (out, sig)


def _own_axis_angles(sts, points, j: int):
    """Angles of a run about the joint's own axis, fitted from A2 over the run itself (a wide span at a large radius
    beats the short sweep), with the axis's error in their covariance
    (:func:`calib.estimators.transmission.joint_angles_fitted_axis`): ``(angles, sigmas, cov)`` as
    :func:`_joint_angles`, NaN where a step lacks A1 or A2; None when fewer than 4 steps have both."""
    from calib.estimators.axes import fit_axis
    from calib.estimators.transmission import joint_angles_fitted_axis
    ok = [i for i, st in enumerate(sts) if {"A1", "A2"} <= set(points(st))]
    if len(ok) < 4:
        return None
    pairs = [(points(sts[i])["A1"], points(sts[i])["A2"]) for i in ok]
    U = _block([t for p in pairs for t in p], points)
    A1, A2 = (np.array([p[k].point_mm for p in pairs]) for k in (0, 1))
    iA2 = (np.arange(len(ok))[:, None] * 6 + np.arange(3, 6)).ravel()
    fit_axis(A2, U[np.ix_(iA2, iA2)], n_mc=0, joint=f"j{j}")       # its checks: the points lie on a circle
    out, cov = np.full(len(sts), np.nan), np.full((len(sts), len(sts)), np.nan)
    out[ok], cov[np.ix_(ok, ok)], _ = joint_angles_fitted_axis(A1, A2, U)
    return out, np.sqrt(np.diag(cov)), cov


def _transmission(steps, points, robot, axes, est, twin, figs, n_mc):
    """Per joint: the angle from A1, A2 about the joint's own axis against the encoder, and the harmonic fit (with
    the angles' full covariance).  A joint whose fit fails, or whose order is not determined, is said so in the
    figures and left out of the running errors; the other joints still count."""
    from calib.estimators.transmission import fit_transmission_error
    from calib.effects import TransmissionError
    if not steps:
        return
    by_joint = _by_joint(steps)
    figs["transmission"] = {}
    fits, failed = {}, []
    for j, sts in sorted(by_joint.items()):
        if j not in axes:
            failed.append(f"joint {j}: no swept axis to measure the angle about")
            continue
        sts.sort(key=lambda s: s["spec"]["meta"]["index"])
        own = _own_axis_angles(sts, points, j)
        meas, sig, cov = own if own is not None else _joint_angles(sts, points, axes[j].value[3:6], full=True)
        enc = np.array([(_encoder_q(s, robot) if _encoder_q(s, robot) is not None
                         else np.asarray(s["spec"]["pose_deg"]) * DEG)[j - 1] for s in sts])
        err = np.angle(np.exp(1j * (meas - (enc - enc[0]))))      # both sides wrap differently past 180 deg
        cov = cov + _reference_quantisation(sts, robot, j)
        ok = np.isfinite(err)
        try:
            res = fit_transmission_error(enc[ok], err[ok], cov[np.ix_(ok, ok)], n_mc=n_mc)
        except RobocalError as exc:
            failed.append(f"joint {j}: {exc}")
            continue
        tv = {}
        if twin is not None:
            for e in twin.scenario.effects:
                if isinstance(e, TransmissionError) and e.joint == j:
                    tv = {"omega": e.order, "amplitude1_rad": float(np.hypot(e.values[0], e.values[len(e.values) // 2]))
                          if len(e.values) > 1 else abs(float(e.values[0]))}
        est.add_set(f"te.j{j}.", res, tv, only=("omega", "amplitude1_rad"))
        nd = res.extras.get("not_determined") or {}
        if "omega" not in nd:
            fits[j] = res
        figs["transmission"][j] = {"encoder_deg": (enc / DEG).tolist(), "error_deg": (err / DEG).tolist(),
                                   "sigma_deg": (sig / DEG).tolist(),
                                   "fit": {k: float(res[k].value) for k in res.names}, "not_determined": nd}
        _commanded(sts, meas, cov, ok, j, est, figs)
    if failed and not fits:
        raise RobocalError("; ".join(failed))
    figs.setdefault("problems", []).extend(f"transmission: {f}" for f in failed)
    return fits


def _reference_quantisation(sts, robot, j: int) -> np.ndarray:
    """Covariance the encoder's quantisation adds to ``meas - (enc - enc[0])`` over a run: each step's count is off
    by up to half a count (uniform: 1/sqrt(12) of a count), and the first step's error enters every difference.  A
    Puma wrist count is 0.005 deg at the joint, as large as the theodolites' angle noise; steps whose joint reading
    is the commanded angle (no tap) carry none."""
    from calib.estimators.coupling import quantisation_sigma
    from calib.estimators.resolution import design_resolution_rad
    s = quantisation_sigma(design_resolution_rad(robot.counts_per_rev[j - 1], robot.gear_ratio[j - 1]))
    tapped = np.array([_encoder_q(st, robot) is not None for st in sts], float)
    E = np.diag(-tapped)
    E[:, 0] += tapped[0]
    E[0] = 0.0
    return s ** 2 * (E @ E.T)


def _setup_model(robot, setup):
    """The description's model with the bench's base pose from the set-up: what the operator knows of the geometry
    (nominal, no effects), for torques and joint axes at a step's pose."""
    from calib.model import MeasurementModel
    from .setup import nominal_theta
    model = MeasurementModel(robot)
    return model, nominal_theta(model, setup)


def _step_loads(st, robot, model, theta):
    """The step's joint readings, total torque about every joint (N m: the description's link weights plus the
    recorded hung masses, from geometry), the joints' axes (N, 3) at that pose in the measurement frame, and the
    torques' derivatives: w.r.t. the geometric parameters (n, P_geometric) and w.r.t. the load points' coordinates
    in their frames (n, 3, summed over the loads: they move together when the lever is measured wrong), and the
    torque of the hung masses alone per kg hung (n,: what a wrong mass changes, the thesis's Delta N)."""
    from .rig import c3_setup
    spec = st["spec"]
    q = _encoder_q(st, robot)
    q = np.asarray(spec["pose_deg"], float) * DEG if q is None else q
    s = c3_setup(spec["setup"], spec["pose_deg"], st["inputs"], model.kin)
    g = model.gravity_n_per_kg(theta)
    loads = s.get("loads", [])
    links = [int(ld["link"]) for ld in loads]
    F = np.array([ld["mass_kg"] * g for ld in loads], float).reshape(-1, 3)
    ctx = model.context(1, point_force_link=links,
                        point_force_mm=np.array([ld["point_mm"] for ld in loads], float).reshape(1, -1, 3),
                        point_force_n=F[None])
    fp = model.kin.forward(q[None], theta[: model.n_geometric])
    ld = model.loads(fp, ctx, derivative=True)
    hung_nm = ld.joint_torque_nm[0] - model.loads(fp, model.context(1)).joint_torque_nm[0]
    mass_kg = float(sum(ld_["mass_kg"] for ld_ in loads))
    # moving a load's point by e_c in its frame j adds (R_j e_c x F) . z_i to joint i's torque (i <= j)
    z = fp.joint_axis[0]
    dpoint = np.zeros((robot.n, 3))
    for b, f in zip(links, F):
        R = fp.frame_R[0, b]
        for i in range(min(b, robot.n)):
            dpoint[i] += np.cross(R.T, f * 1e-3) @ z[i]
    return q, ld.joint_torque_nm[0], z, ld.dtau_dgeo[0], dpoint, hung_nm / mass_kg if mass_kg > 0 else 0 * hung_nm


def _swept_geometry(model, theta, est):
    """The geometry the torques are computed with, and each parameter's 1-sigma: the session's own DH estimates
    from the sweeps where it has them (they run first), the description within its tolerances
    (:data:`acq.session.setup.DESCRIPTION_TOLERANCES`) elsewhere.  Why: a Puma's a3 can be 10 mm off its drawing,
    which is 2 % of a compliance lever."""
    from .setup import DESCRIPTION_TOLERANCES as tol
    theta = theta.copy()
    sig = np.array([tol["length_mm"] if n.startswith("j") and n.endswith("_mm") else
                    tol["angle_deg"] * DEG if n.startswith("j") and n.endswith("_rad") else 0.0
                    for n in model.kin.names])
    for e in est.items:
        name = e["name"][3:]
        if e["name"].startswith("dh.") and name in model.kin.index and not e["held"] and np.isfinite(e["error"]):
            theta[model.index[name]], sig[model.kin.index[name]] = e["value"], e["error"]
    return theta, sig


def _torque_cov(per_step, j, sig_geo) -> np.ndarray:
    """Covariance of the torques about joint j over a loading series, from the geometry they were computed with
    (``sig_geo``, per geometric parameter) and the load point's position (a lever measured with a tape: the tool
    tolerance), each common to the whole series -- the thesis's Delta L_j and Delta theta_ij terms, from the model's
    torque derivative instead of N L cos(theta); and the mass hung at each step (the thesis's Delta N: each step's
    weights weighed to ``load_mass_kg``, independent from step to step)."""
    from .setup import DESCRIPTION_TOLERANCES as tol
    Jg = np.array([p[3][j - 1] for p in per_step]) * sig_geo                  # (steps, P)
    Jp = np.array([p[4][j - 1] for p in per_step]) * tol["tool_mm"]           # (steps, 3)
    dN = np.array([p[5][j - 1] for p in per_step]) * tol["load_mass_kg"]      # (steps,)
    return Jg @ Jg.T + Jp @ Jp.T + np.diag(dN ** 2)


def _commanded(sts, meas, cov, ok, j, est, figs):
    """Section 4.4's E_a (measured minus commanded angle) of a transmission run, its slope as an estimate."""
    from calib.estimators.transmission import commanded_angle_errors
    desired = np.array([s["spec"]["pose_deg"][j - 1] for s in sts], float)[ok] * DEG
    try:
        ea = commanded_angle_errors(meas[ok], cov[np.ix_(ok, ok)], desired)
    except RobocalError as exc:
        figs.setdefault("problems", []).append(f"transmission: joint {j}: E_a: {exc}")
        return
    est.add_set(f"te.j{j}.", ea, only=("E_a_slope",))
    figs["transmission"][j]["E_a_deg"] = [0.0] + (ea.value[:-1] / DEG).tolist()


def _resolution(steps, points, robot, est, twin, figs):
    """The encoder-resolution run (Fig 5.14): per joint, measured angle (A1, A2 about the run's own axis, fitted from
    A2 over the run) against the tapped counts, the axis's error propagated into the slope's
    (:func:`calib.estimators.resolution.encoder_resolution_fitted_axis`); truth the description's resolution (the
    twin's encoders are the description's)."""
    from calib.estimators.resolution import design_resolution_rad, encoder_resolution_fitted_axis
    if not steps:
        return
    by_joint = _by_joint(steps)
    figs["resolution"] = {}
    for j, sts in sorted(by_joint.items()):
        sts = sorted((s for s in sts if s.get("counts") is not None and len(s["counts"])
                      and {"A1", "A2"} <= set(points(s))), key=lambda s: s["spec"]["meta"]["index"])
        pairs = [(points(s)["A1"], points(s)["A2"]) for s in sts]
        counts = np.array([np.mean(s["counts"], 0)[j - 1] for s in sts])
        design = design_resolution_rad(robot.counts_per_rev[j - 1], robot.gear_ratio[j - 1])
        signed = counts * np.sign(robot.gear_ratio[j - 1])
        res = encoder_resolution_fitted_axis(signed, [a.point_mm for a, _ in pairs], [b.point_mm for _, b in pairs],
                                             _block([t for p in pairs for t in p], points), design, joint=f"j{j}")
        meas, C = res.extras["angle_rad"], res.extras["angle_cov_rad2"]
        tv = (_resolution_truth(twin, robot, sts, np.ones(len(sts), bool), j, signed, C, design)
              if twin is not None else {})
        est.add_set(f"resolution.j{j}.", res, tv, only=("rad_per_count", "scale"))
        figs["resolution"][j] = {"counts": counts.tolist(), "angle_deg": (meas / DEG).tolist(),
                                 "sigma_deg": (np.sqrt(np.diag(C)) / DEG).tolist(),
                                 "rad_per_count": float(res["rad_per_count"].value),
                                 "residual_deg": (res.extras["residual_rad"] / DEG).tolist()}


def _resolution_truth(twin, robot, sts, ok, j, signed_counts, cov, design) -> dict:
    """The twin's resolution in the estimator's terms: the same fit on the twin's true joint angles (description's
    encoders plus the joint's running errors, e.g. its transmission error) at the run's counts, without noise.  Why:
    the slope the run measures is the resolution achieved over the run, which the transmission error tilts by more
    than the fit's error; the description's value alone would not be what it estimates (as ``_compliance_truth``)."""
    from calib.estimators.resolution import encoder_resolution
    counts = np.array([np.mean(s["counts"], 0) for s in sts])[ok]
    q = robot.joint_from_counts(counts)
    try:
        _, th = twin.true_points(q, twin.context(len(q)))
        clean = encoder_resolution(signed_counts, th[:, j - 1] - th[0, j - 1], cov, design)
    except RobocalError:
        return {"rad_per_count": design, "scale": 1.0}
    return {k: float(clean[k].value) for k in ("rad_per_count", "scale")}


def _compliance(steps, points, robot, axes, est, twin, figs, n_mc, setup=None, problems=None):
    """Joint stiffness from the deflection (angle of A1 -> A2 about the joint's axis) against the torque about that
    axis, the torque computed from the geometry at each step's pose with its recorded loads.  A joint about which the
    loads produce no torque (its axis along gravity, a lever along the axis) gets no number: "not determined" and
    why, in ``problems``."""
    from calib.estimators.compliance import two_slope_fit
    from calib.effects import JointCompliance
    if not steps:
        return
    problems = [] if problems is None else problems
    model, theta = _setup_model(robot, setup or {})
    theta, sig_geo = _swept_geometry(model, theta, est)
    by_joint = _by_joint(steps)
    figs["compliance"] = {}
    fits = {}
    for j, sts in sorted(by_joint.items()):
        sts.sort(key=lambda s: s["spec"]["meta"]["index"])
        per_step = [_step_loads(s, robot, model, theta) for s in sts]
        T = np.array([p[1][j - 1] for p in per_step])
        # the joint's axis at the loading pose (it is not the swept one when the pose differs)
        axis = per_step[0][2][j - 1]
        applied = np.ptp(T)
        if not np.isfinite(applied) or applied < 0.05:
            problems.append(f"compliance: joint {j}: not determined: the loads change the torque about joint {j} by "
                            f"{applied:.3g} N m at the loading pose (its axis is along gravity or the lever along "
                            f"the axis): hang them where they turn the joint")
            continue
        sign = 1.0 if T[np.argmax(np.abs(T))] >= 0 else -1.0        # the fit's branches are for positive torques
        defl, sig, dcov = _joint_angles(sts, points, axis, full=True)
        unload = np.array([s["spec"]["meta"]["phase"] == "unload" for s in sts])
        try:
            res = two_slope_fit(sign * T, sign * defl, unload, dcov, n_mc=n_mc,
                                sigma_torque_Nm=_torque_cov(per_step, j, sig_geo))
        except RobocalError as exc:                 # e.g. "not determined": the other joints still count
            problems.append(f"compliance: joint {j}: {exc}")
            continue
        raw, tv = {}, {}
        single = bool(res.extras.get("single_slope"))
        if twin is not None:
            for e in twin.scenario.effects:
                if isinstance(e, JointCompliance) and e.joint == j:
                    c1, c2, tb, h = e.values
                    # the fit reads unloading minus loading in its own sign (d = c(T) - h/2 x load direction)
                    raw = {"K1_Nm_per_rad": 1 / c1, "K2_Nm_per_rad": 1 / c2, "breakpoint_Nm": tb,
                           "offset_rad": sign * h}
                    tv = _compliance_truth(e, j, T, sign, unload, res.extras.get("cov_rad2", dcov), raw, single)
        K = res["K1_Nm_per_rad"]
        if not (np.isfinite(K.value) and np.isfinite(K.error) and K.value > 0 and K.error < K.value):
            problems.append(f"compliance: joint {j}: not determined: K1 = {K.value:.4g} +- {K.error:.2g} N m/rad "
                            f"(torque range {applied:.3g} N m, deflection sigma {np.nanmean(sig):.2g} rad)")
            continue
        span = sorted(abs(t) for t in res.extras.get("torque_range_Nm", (0.0, 0.0)))
        for e in res.estimates():
            if e.name not in ("K1_Nm_per_rad", "K2_Nm_per_rad", "breakpoint_Nm", "offset_rad"):
                continue
            t, r = tv.get(e.name), raw.get(e.name)
            extra = {}
            if single and e.name == "K1_Nm_per_rad":
                extra = {"single_slope": True,
                         "note": f"one slope over every load ({span[0]:.3g} .. {span[1]:.3g} N m): the breakpoint is "
                                 f"not determined, so K2 and the breakpoint are not reported; hang more, smaller "
                                 f"loads on each side of it to tell two slopes apart"}
            if t is not None and r is not None and abs(t - r) > 0.1 * e.error:
                extra.update(truth_raw=float(r))
                extra["note"] = "; ".join(filter(None, [extra.get("note"), "truth: the same fit on the twin's "
                                                        "noise-free deflections at the same torques"]))
            est.add(f"compliance.j{j}.{e.name}", e.value, e.error, e.unit, truth_value=t, **extra)
        fits[j] = res
        figs["compliance"][j] = {"torque_nm": T.tolist(), "deflection_deg": (defl / DEG).tolist(),
                                 "unloading": unload.tolist(), "fit": {k: float(res[k].value) for k in res.names}}
    return fits


def _compliance_truth(effect, j, T, sign, unload, cov, raw: dict, single: bool) -> dict:
    """The twin's stiffness in the estimator's terms.  When the fit told the two slopes apart (``single`` false),
    the twin's own slopes, breakpoint and dead zone.  When it could not place the breakpoint, its ``K1`` is one
    slope over every load: its truth is that same single-slope fit, with the same weights ``cov``, on the
    deflections the twin's compliance effect makes at the same torques, without noise (the twin's two slopes are
    not what it estimates, and which mean of them it is depends on the weights)."""
    if not single:
        return raw
    from calib.effects import Loads, PoseContext
    from calib.estimators.compliance import single_slope_fit
    n = max(effect.joint, j)
    tau = np.zeros((len(T), n))
    tau[:, j - 1] = T
    ctx_dir = np.zeros((len(T), n))
    ctx_dir[:, j - 1] = np.where(unload, -1.0, 1.0)
    ctx = PoseContext(len(T), n, load_direction=ctx_dir)
    d, _ = effect.joint_delta(np.zeros((len(T), n)), ctx, Loads(tau, np.zeros((len(T), n, 3))), effect.values)
    try:
        clean = single_slope_fit(sign * T, sign * d[:, j - 1], unload, cov)
    except RobocalError:
        return {}
    return {**raw, **{e.name: float(e.value) for e in clean.estimates() if e.name in raw}}


def _link(steps, setup, est, twin, figs, n_mc, robot=None):
    """Flexural rigidity of the link from the dial gauges (:func:`calib.estimators.link_compliance.link_rigidity`):
    EI with its error when the gauges show bending, else a 95 % one-sided lower bound -- the thesis's own finding on
    the Puma (section 5.7: link compliance negligible against joint compliance) stated as a result.  Its truth is the
    scenario's link compliance of that link (a rigid link, none, when the scenario has none enabled)."""
    from calib.effects import LinkCompliance
    from calib.estimators.link_compliance import RigidityBound, link_rigidity
    if not steps:
        return
    cfg = setup["link"]
    x, a, P, y = [], [], [], []
    for st in steps:
        s = st["spec"]["setup"]
        for g, gx in enumerate(s["gauges_x_mm"]):
            v = st["inputs"].get(f"gauge{g + 1}_mm")
            if v is None:
                continue
            x.append(gx)
            a.append(s["load_x_mm"])
            P.append(_link_load_n(st["inputs"], s))
            y.append(v)
    res = link_rigidity(x, a, P, y, sigma_mm=0.001, second_moment_mm4=cfg.get("second_moment_mm4"), n_mc=n_mc)
    tv = {}
    if twin is not None:
        tv = {"EI_Nmm2": 1.0 / float(e.values[0]) for e in twin.scenario.effects
              if isinstance(e, LinkCompliance) and e.joint == cfg["joint"]}
    figs["link"] = {"x_mm": x, "load_n": P, "deflection_mm": y, "load_x_mm": a}
    prefix = f"link.j{cfg['joint']}."
    if isinstance(res, RigidityBound):
        est.add_bound(f"{prefix}EI_lower_bound_Nmm2", res.EI_lower_bound_Nmm2, "N mm^2", "lower", res.confidence,
                      tv.get("EI_Nmm2"), detection_limit_Nmm2=res.detection_limit_Nmm2,
                      compliance_per_Nmm2=res.compliance_per_Nmm2,
                      compliance_error_per_Nmm2=res.compliance_error_per_Nmm2,
                      largest_deflection_mm=res.largest_deflection_mm, sigma_mm=res.sigma_mm,
                      **({"truth_note": "rigid: the scenario has no link compliance"} if twin is not None and not tv
                         else {}),
                      note=f"no significant bending (largest deflection {res.largest_deflection_mm:.2g} mm, gauge "
                           f"noise {res.sigma_mm:.2g} mm): the link is at least this stiff at "
                           f"{100 * res.confidence:g} % confidence")
        figs["link"].update(EI_lower_bound_Nmm2=res.EI_lower_bound_Nmm2, confidence=res.confidence)
        return
    est.add_set(prefix, res, tv, only=("EI_Nmm2",))
    figs["link"]["EI_Nmm2"] = float(res["EI_Nmm2"].value)


def _link_load_n(inputs: dict, spec_setup: dict) -> float:
    """The force hung at a link step (N): the mass the operator entered (``load_kg``, contract C3) times standard
    gravity; sessions recorded before that entered ``load_n``; else the planned load."""
    if inputs.get("load_kg") is not None:
        return float(inputs["load_kg"]) * G0_M_S2
    return float(inputs.get("load_n", spec_setup["load_n"]))


def _coupling(steps, robot, est, twin, figs, n_mc):
    """sigma_jk per coupled pair from the tapped counts, every repeat of a pair used: the scatter of the repeats
    (servo repeatability) pooled over the pairs, quantisation as the floor (:func:`coupling_from_repeats`)."""
    from calib.estimators.coupling import coupling_from_repeats, further_correction, quantisation_sigma
    if not steps:
        return
    runs: dict[tuple, dict] = {}
    for st in steps:
        m = st["spec"]["meta"]
        if st.get("counts") is None or len(st["counts"]) == 0:
            continue
        runs.setdefault((m["j"], m["k"]), {}).setdefault(m.get("repeat", 0), {})[m["phase"]] = np.mean(st["counts"], 0)
    S = 2 * np.pi / (robot.counts_per_rev * robot.gear_ratio)           # joint rad per count, coupling ignored
    pairs, q = {}, 0.0
    for (j, k), reps in sorted(runs.items()):
        rows = [(ph["with"] - ph["return"], ph["alone"] - ph["start"], ph["with"], ph["return"]) for ph in reps.values()
                if all(p in ph for p in ("start", "alone", "return", "with"))]
        if not rows:
            continue
        th_with = np.array([w[k - 1] * S[k - 1] for w, _, _, _ in rows])            # S_k xi_k of eq 4.7.1
        th_alone = np.array([a[k - 1] * S[k - 1] for _, a, _, _ in rows])
        th_j = np.array([robot.joint_from_counts(w)[j - 1] - robot.joint_from_counts(r)[j - 1]
                         for _, _, w, r in rows])
        pairs[(j, k)] = (th_with, th_alone, th_j)
        q = max(q, quantisation_sigma(abs(S[k - 1])))
    figs["coupling"] = {}
    if not pairs:
        return
    res = coupling_from_repeats({f"sigma{j}{k}": v for (j, k), v in pairs.items()}, q * np.sqrt(2))
    # eq 4.7.2: what the controller compensates with (the description's factors) against what was measured
    further = further_correction(res, {f"sigma{j}{k}": float(robot.coupling[k - 1, j - 1]) for (j, k) in pairs})
    est.add_set("coupling.", further)
    for (j, k), (th_with, th_alone, th_j) in pairs.items():
        name = f"sigma{j}{k}"
        tv = {name: float(robot.coupling[k - 1, j - 1])} if twin is not None else {}
        est.add_set("coupling.", res.subset([name]), tv)
        figs["coupling"][f"{j}{k}"] = {"theta_j_deg": float(np.mean(th_j)) / DEG,
                                       "theta_k_alone_deg": float(np.mean(th_alone)) / DEG,
                                       "theta_k_with_deg": float(np.mean(th_with)) / DEG,
                                       "sigma": float(res[name].value), "repeats": int(th_j.size),
                                       "error_type": res.extras["type"]}
