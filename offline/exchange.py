"""Import and export: raw readings (CSV/JSON) and pose measurements (the pose CSV of :mod:`calib.posecsv`).

Raw-readings CSV (one row per theodolite reading; header row; ``#`` comments):

=================  ===========================================================================
column             meaning
=================  ===========================================================================
``step``           step key (``ruler/p0/C``, ``sweep/j2/03``, ``poses/004`` ...): groups readings
``procedure``      ruler, sweep, poses, transmission, compliance (as in the session)
``station``        a station of the set-up (``stations.names``, default A and B)
``target``         target name (C, D, E, P, A1, A2)
``face``           1 or 2
``hz_deg``         horizontal circle reading, deg (clockwise)
``v_deg``          zenith angle, deg
``q1_deg``..       joint readings at the step, deg (optional)
``raw_hex``        the instrument's reply frame, hex (optional)
=================  ===========================================================================

Pose CSV: see :mod:`calib.posecsv` (``q1``..``q6`` deg, ``x``, ``y``, ``z`` mm, ``pose``, ``time``, ``payload``,
``temperature``, ``dir1``..``dir6``).  An imported pose CSV becomes a session whose ``poses`` steps carry the
measured positions as operator inputs ``x_mm``, ``y_mm``, ``z_mm``, so ``robocal reprocess`` identifies from it.
"""
from __future__ import annotations

import csv
import io
import json
import math
import os
import time
import warnings
from pathlib import Path

import numpy as np

from acq.session.imported import imported_conditions, imported_labels, imported_point, pose_steps
from acq.session.setup import setup_robot, setup_stations, standard_setup, station_names
from acq.session.setup_file import read_setup, setup_from_text
from calib.errors import RobocalError
from calib.fileio import atomic_write_text
from calib.textin import read_text
from calib.units import DEG

from offline.reduction.session import load_session

from acq.session.setup_types import BenchSetup, mark_index, setup_of
from acq.session.store import SessionStore, StepRecord, connect_readonly, json_column
from calib.estimators.points import StationFit, locate_targets
from calib.posecsv import csv_fields, raw_rows, read_pose_csv, write_pose_csv
from offline.reduction.joints import reading_q
from offline.reduction.stages.ruler import fitted_stations

READING_COLUMNS = ["step", "procedure", "station", "target", "face", "hz_deg", "v_deg", "q1_deg", "q2_deg", "q3_deg",
                   "q4_deg", "q5_deg", "q6_deg", "raw_hex"]


def export_readings_csv(db: str, out: str) -> int:
    conn = connect_readonly(db)
    try:
        rows = conn.execute(
            "SELECT s.key, s.procedure, r.station, r.target, r.face, r.hz_rad, r.v_rad, s.spec_json, r.raw "
            "FROM reading r JOIN step s ON r.step_id = s.step_id WHERE s.status='accepted' AND r.attempt=s.attempts "
            "ORDER BY s.seq, r.reading_id").fetchall()
    finally:
        conn.close()
    f = io.StringIO(newline="")
    w = csv.writer(f)
    w.writerow(READING_COLUMNS)
    for key, proc, st, tg, face, hz, v, spec, raw in rows:
        q = json_column(spec, f"{db}: step {key!r}: spec_json").get("pose_deg") or [""] * 6
        w.writerow([key, proc, st, tg, face, f"{hz / DEG:.10f}", f"{v / DEG:.10f}", *q, raw.hex()])
    atomic_write_text(out, f.getvalue())
    return len(rows)


def export_json(db: str, out: str) -> None:
    d = load_session(db)
    steps = []
    for s in d.steps:
        steps.append({"key": s["key"], "procedure": s["procedure"], "spec": s["spec"], "inputs": s["inputs"],
                      "readings": [{**r, "hz_deg": r["hz_rad"] / DEG, "v_deg": r["v_rad"] / DEG}
                                   for r in s["readings"]],
                      "encoder_counts_mean": None if s["counts"] is None else np.mean(s["counts"], 0).tolist()})
    doc = {"format": "robocal-session-json", "version": 1, "session": {k: v for k, v in d.session.items()},
           "plan": d.plan, "setup": dict(d.setup.doc), "steps": steps}
    text = json.dumps(doc, indent=1, default=str)
    if out == "-":                       # '-' is standard output, as for reprocess --json and demo --json
        print(text)
    else:
        atomic_write_text(out, text)


def stored_plan_setup(db: str) -> tuple[dict, dict]:
    """The plan and set-up a session database was created with (read-only: nothing is touched)."""
    conn = connect_readonly(db)
    try:
        row = conn.execute("SELECT plan_json, setup_json FROM session ORDER BY session_id LIMIT 1").fetchone()
    finally:
        conn.close()
    if row is None:
        raise RobocalError(f"{db}: holds no session (a database left by a crash while it was created)")
    return json_column(row[0], f"{db}: session plan_json"), setup_from_text(row[1], f"{db}: session setup_json")


def session_robot(db: str):
    """The robot a session database was recorded with: its set-up's ``robot`` and chain cut."""
    return setup_robot(BenchSetup.of(stored_plan_setup(db)[1]))        # checked as it was read


def pose_arrays(db: str) -> dict:
    """The pose-set steps of a session as arrays: encoder joint readings, intersected tool-target positions (with the
    stations the session's own ruler steps give) and their covariances, step keys and sighting geometry; for an
    imported pose CSV also the conditions, split, station and pose labels its rows carried; the raw readings behind
    each intersected point (``readings``, the target they sight ``readings_target``) and the ``stations`` they were
    intersected with (the both-faces noise estimate)."""
    d = load_session(db)
    robot = setup_robot(d.setup)
    ruler = [s for s in d.steps if s["procedure"] == "ruler"]
    fit = fitted_stations(ruler, d.setup)[1] if ruler else StationFit.exact(setup_stations(d.setup))
    stations = fit.stations
    q, P, C, keys, angle, used, raw = [], [], [], [], [], [], []
    for s in d.steps:
        if s["procedure"] != "poses":
            continue
        pts = locate_targets(s["readings"], fit) if s["readings"] else {}
        if "P" in pts:
            p, cov = pts["P"][0], pts["P"][1]
        elif imported_point(s) is not None:
            p, cov = imported_point(s)
        else:
            continue
        q.append(reading_q(s, robot))
        P.append(p)
        C.append(cov)
        keys.append(s["key"])
        used.append(s)
        raw.append([r for r in s["readings"] if r["target"] == "P"] if "P" in pts else [])
        sa, sb = list(stations.values())[:2]
        ua, ub = p - sa.position, p - sb.position
        angle.append(np.degrees(np.arccos(np.clip(ua @ ub / (np.linalg.norm(ua) * np.linalg.norm(ub)), -1, 1))))
    if not q:
        raise RobocalError(f"{db}: no pose-set steps")
    out = {"q_rad": np.array(q), "points_mm": np.array(P), "cov_mm2": np.array(C), "keys": keys,
           "procedure": ["poses"] * len(q), "sighting_angle_deg": np.array(angle), "raw_angles": False,
           **imported_conditions(used, robot.n), "readings": raw, "readings_target": ["P"] * len(q),
           "stations": stations}
    for name in ("station", "split", "target", "pose"):
        labels = imported_labels(used, name)
        if labels is not None:
            out[name] = labels
    return out


def export_poses_csv(db: str, out: str) -> int:
    """Pose-set steps as a pose CSV: encoder joint readings and the intersected tool-target positions."""
    a = pose_arrays(db)
    sig = np.sqrt(np.diagonal(a["cov_mm2"], axis1=1, axis2=2))
    extra = {f"sigma_{c}_mm": sig[:, i] for i, c in enumerate("xyz")}
    # what an imported pose CSV carried goes back out under its own column names
    extra |= {col: a[key] for col, key in (("time", "time_s"), ("payload", "payload_kg"),
                                           ("temperature", "temperature_c")) if key in a}
    if "direction" in a:
        extra |= {f"dir{j + 1}": a["direction"][:, j] for j in range(a["direction"].shape[1])}
    labels = {k: a[k] for k in ("pose", "station", "split", "target") if k in a}
    write_pose_csv(out, a["q_rad"], a["points_mm"], extra, prismatic=session_robot(db).prismatic, labels=labels)
    return len(a["q_rad"])


def _detect(path: str) -> str:
    for lineno, line in enumerate(read_text(path).splitlines(), 1):
        if line.strip() and not line.startswith("#"):
            cols = [c.strip() for c in line.strip().split(",")]
            if "q1" in cols or {"x", "y", "z"} <= set(cols):     # joint columns may carry a description's names
                return "poses"
            if "hz_deg" in cols:
                return "readings"
            raise RobocalError(f"{path}: line {lineno}: neither a raw-readings CSV (needs hz_deg) nor a pose CSV "
                               f"(needs q1, or x, y, z)")
    raise RobocalError(f"{path}: empty file")


def partial_path(db: str | Path) -> Path:
    """Where ``robocal import`` builds ``db`` until it is complete (``--resume`` continues it)."""
    p = Path(db)
    return p.with_name(p.name + ".importing")


def import_file(path: str, db: str, setup_json: str | None = None, resume: bool = False) -> tuple[str, int]:
    """A new session in ``db`` from a readings or pose CSV; returns (kind, steps).

    Nothing half-made: the whole input is read and checked first, the database is built in ``DB.importing`` and
    renamed to ``db`` only when every step is in.  An interrupted import leaves ``DB.importing``; ``resume`` continues
    it (steps already in are kept), a new import without ``resume`` starts it afresh."""
    if Path(db).exists():
        raise RobocalError(f"{db}: exists already: import writes a new session database (choose another --db)")
    kind = _detect(path)
    setup = read_setup(setup_json) if setup_json else _default_setup()
    typed = setup_of(setup, str(setup_json or "the standard set-up"))
    steps = _pose_steps(path, typed) if kind == "poses" else _reading_steps(path, typed)
    part = partial_path(db)
    if resume and not part.exists():
        raise RobocalError(f"{db}: no unfinished import to resume ({part} does not exist)")
    if not resume:
        for stale in (part, Path(f"{part}-wal"), Path(f"{part}-shm")):
            stale.unlink(missing_ok=True)
    plan = {"procedures": [], "imported_from": str(path), "kind": kind}
    if resume:
        store = SessionStore.open(part)
        if json.loads(store.session_row()["plan_json"]).get("imported_from") != str(path):
            store.close()
            raise RobocalError(f"{part}: is the unfinished import of another file; resume with that file, or "
                               "import without --resume to start afresh")
    else:
        store = SessionStore.create(part, f"imported {kind} from {Path(path).name}", plan, setup,
                                    metadata={"emulated": False, "imported": True})
    try:
        done = store.done_keys()
        device = None
        for rec in steps:
            if rec.key in done:
                continue
            if rec.readings:
                device = device or store.add_device("imported theodolites", "csv", str(path), {})
                for r in rec.readings:
                    r["device_id"] = device
            store.write_step(rec)
        store.finish("success")
        store.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    finally:
        store.close()
    if Path(db).exists():
        raise RobocalError(f"{db}: appeared while importing; the import is kept in {part}")
    os.replace(part, db)
    return kind, len(steps)


def _default_setup() -> dict:
    return standard_setup()


def _pose_steps(path: str, setup: BenchSetup) -> list[StepRecord]:
    """Every row of a pose CSV as a ``poses`` step, each measured column kept (:mod:`acq.session.imported`)."""
    # a set-up naming a description reads the file as identify does with it (joint names, conventions, tool points)
    robot = setup_robot(setup)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t = read_pose_csv(path, robot.n, robot.prismatic, robot=robot if setup.robot else None)
    for w in caught:
        if "ignoring unknown column" not in str(w.message):
            warnings.warn(w.message, stacklevel=2)
    if t.ignored_columns:
        warnings.warn(f"{path}: column(s) {', '.join(t.ignored_columns)} kept in the session as written; the "
                      "calibration does not use them", stacklevel=2)
    if t.points_mm is None:
        raise RobocalError(f"{path}: a pose CSV to import needs the measured x, y, z columns")
    out = pose_steps(t, raw_rows(path), str(path))
    _unique_keys(path, out)
    return out


def _unique_keys(path: str, steps: list[StepRecord]) -> None:
    seen: set[str] = set()
    for rec in steps:
        if rec.key in seen:
            raise RobocalError(f"{path}: step {rec.key!r} appears twice (pose ids must be unique, or differ in "
                               "their target)")
        seen.add(rec.key)


def _finite(text: str, what: str) -> float:
    v = float(text)
    if not math.isfinite(v):
        raise ValueError(f"{what} {text!r} is not a finite number")
    return v


def _reading_steps(path: str, setup: BenchSetup | None = None) -> list[StepRecord]:
    """The readings of a raw-readings CSV grouped into steps; ``station`` must name one of the set-up's stations
    (default set-up: A and B)."""
    stations = station_names(setup or setup_of(_default_setup()))
    steps: dict[str, dict] = {}
    lines = [(n, ln) for n, ln in enumerate(read_text(path).splitlines(), 1) if not ln.startswith("#")]
    if not lines:
        raise RobocalError(f"{path}: empty file")
    header_line, header = lines[0]
    cols = [c.strip() for c in csv_fields(header, path, header_line)]
    unknown = set(cols) - set(READING_COLUMNS)
    if unknown:
        warnings.warn(f"{path}: ignoring unknown column(s) {', '.join(sorted(unknown))}")
    for need in ("step", "procedure", "station", "target", "face", "hz_deg", "v_deg"):
        if need not in cols:
            raise RobocalError(f"{path}: line {header_line}: missing column {need!r}")
    for lineno, line in lines[1:]:
        if not line.strip():
            continue
        fields = csv_fields(line, path, lineno)
        if len(fields) != len(cols):
            raise RobocalError(f"{path}: line {lineno}: {len(fields)} fields, the header has {len(cols)}")
        row = dict(zip(cols, fields))
        if row["station"] not in stations:
            raise RobocalError(f"{path}: line {lineno}: column station: {row['station']!r} is not a station of the "
                               f"set-up (its stations: {', '.join(stations)})")
        try:
            face = int(row["face"])
            hz, v = _finite(row["hz_deg"], "hz_deg") * DEG, _finite(row["v_deg"], "v_deg") * DEG
            if face not in (1, 2):
                raise ValueError("column face: must be 1 or 2")
            q = [_finite(row[f"q{j}_deg"], f"q{j}_deg") for j in range(1, 7)] if row.get("q1_deg") else None
            raw = bytes.fromhex(row.get("raw_hex") or "")
            _meta_from_key(row["step"])
        except (ValueError, TypeError, KeyError, RobocalError) as exc:
            raise RobocalError(f"{path}: line {lineno}: {exc}") from None
        s = steps.setdefault(row["step"], {"procedure": row["procedure"], "q": q, "readings": []})
        s["readings"].append({"attempt": 1, "device_id": None, "station": row["station"], "target": row["target"],
                              "face": face, "repeat": 0, "hz_rad": hz, "v_rad": v, "t_wall_s": 0.0,
                              "t_mono_s": 0.0, "command": "imported", "raw": raw})
    now = time.time()
    out = []
    for key, s in steps.items():
        spec = {"pose_deg": s["q"], "meta": _meta_from_key(key), "targets": [], "setup": {}}
        out.append(StepRecord(key, s["procedure"], key, "imported", "accepted", 1, now, now, spec, "",
                              s["readings"], [], [], []))
    return out


def _meta_from_key(key: str) -> dict:
    """Recover the procedure bookkeeping from a step key (``sweep/j2/03`` -> joint 2, index 3)."""
    parts = key.split("/")
    meta: dict = {}
    try:
        if parts[0] == "ruler":
            meta = {"placement": int(parts[1][1:]), "mark": mark_index(parts[2])}
        elif parts[0] == "sweep" and parts[1] == "p":              # point P of d3 (eq 4.3.15); L_p from the set-up
            meta = {"point": "P"}
        elif parts[0] in ("sweep", "te", "compliance"):
            meta = {"joint": int(parts[1][1:]), "index": int(parts[2])}
        elif parts[0] == "poses":
            meta = {"index": int(parts[1]) if parts[1].isdigit() else 0}
    except (IndexError, ValueError):
        raise RobocalError(f"step key {key!r} does not follow the session's pattern (e.g. sweep/j2/03)") from None
    return meta
