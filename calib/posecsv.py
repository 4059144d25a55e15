"""The pose-measurement CSV: joint readings and, optionally, measured tool-target positions and pose conditions.

Format (shared by ``robocal plan``, ``import``, ``identify``, ``diagnose``, ``locate`` and ``evaluate``): a header row,
then one row per measurement.  Lines starting with ``#`` are comments; ``# angle_unit = rad`` and
``# length_unit = m`` comment lines declare the file's units (the ``--angle-unit`` / ``--length-unit`` options say the
same per command; default degrees and mm).

========================  ===============================================================================
column                    meaning
========================  ===============================================================================
``q1`` .. ``qn``          joint readings (angle unit; length unit for a prismatic joint), or, with a robot
                          description, one column per reading named as the description names it (a URDF's
                          joint names, or the readings of its reading conventions)
``x``, ``y``, ``z``       tool-target position in the instrument frame (length unit; all three, or none)
``x<T>``, ``y<T>``,       the position of tool point ``T`` (several targets per row, e.g. ``x1, y1, z1, x2 ..``);
``z<T>``                  targets the description does not name are ignored with a warning
``target``                which tool point the row's x, y, z measure (a name from the description)
``pose``                  pose id (text): rows with the same pose and different targets are one pose
``split``                 ``fit`` or ``test``: the data's own held-out split
``station``               instrument set-up the row was measured from (re-stationing: one transform each)
``hz_deg``, ``v_deg``,    a polar instrument's raw reading of the target (laser tracker, total station), in
``dist_mm``               the station's frame; used when x, y, z are absent
``rx_deg`` .. ``rz_deg``  the measured frame's orientation, instrument frame: R = Rz(rz) Ry(ry) Rx(rx)
                          (:mod:`calib.orientation`: one row is one pose)
``time``                  s
``payload``               kg
``temperature``           deg C
``dir1`` .. ``dirn``      +1 / -1: the sign of each joint's last motion before the pose was reached
``sigma_x_mm`` ..         1-sigma uncertainty of x, y, z (mm)
``sigma_z_mm``
========================  ===============================================================================

Unknown columns are kept as text (``PoseTable.columns``, for grouping in ``evaluate``) and reported with a warning; a
malformed row is an error naming the file, the line and the column.
"""
from __future__ import annotations

import csv
import io
import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .approach import infer, time_column as find_time_column
from .errors import RobocalError
from .fileio import atomic_write_text
from .textin import read_text
from .units import DEG

ANGLE_UNITS = {"deg": DEG, "rad": 1.0}
LENGTH_UNITS = {"mm": 1.0, "m": 1000.0}
SPLITS = ("fit", "test")
CONDITION_COLUMNS = {"time": ("time_s", -math.inf, math.inf), "payload": ("payload_kg", 0, 1e4),
                     "temperature": ("temperature_c", -100, 200)}
FIXED_COLUMNS = {"x", "y", "z", "pose", "target", "split", "station", "sigma_x_mm", "sigma_y_mm", "sigma_z_mm",
                 "hz_deg", "v_deg", "dist_mm", "rx_deg", "ry_deg", "rz_deg"} | set(CONDITION_COLUMNS)
_UNIT_LINE = re.compile(r"^\s*#\s*(angle_unit|length_unit)\s*[:=]\s*\"?(\w+)\"?\s*$")


@dataclass
class PoseTable:
    q_rad: np.ndarray                         # (N, n) joint variables (rad, mm for prismatic joints)
    points_mm: np.ndarray | None = None       # (N, 3)
    pose_id: list[str] = field(default_factory=list)
    time_s: np.ndarray | None = None
    payload_kg: np.ndarray | None = None
    temperature_c: np.ndarray | None = None
    direction: np.ndarray | None = None       # (N, n)
    sigma_mm: np.ndarray | None = None        # (N, 3)
    source: str = "<memory>"
    ignored_columns: list[str] = field(default_factory=list)
    readings: np.ndarray | None = None        # (N, m) controller readings (rad / mm) before reading conventions
    target: list[str] | None = None           # tool point name per row (None: the description's default point)
    split: list[str] | None = None            # "fit" / "test" per row
    station: list[str] | None = None          # instrument set-up per row
    polar: np.ndarray | None = None           # (N, 3) hz (rad), v (rad), distance (mm)
    orientation_rad: np.ndarray | None = None     # (N, 3) roll, pitch, yaw
    line: list[int] = field(default_factory=list)  # source line of each row
    columns: dict[str, list[str]] = field(default_factory=dict)   # other columns, as text (grouping)
    cov_mm2: np.ndarray | None = None         # (N, 3, 3) covariance of points_mm when it is not sigma_mm's
    direction_note: str = ""                  # how ``direction`` was inferred from the measurement order, if it was

    @property
    def n(self) -> int:
        return len(self.q_rad)

    def groups(self, name: str) -> list[str] | None:
        """Per-row labels of a grouping column (station, split, target, pose or any kept text column)."""
        if name in ("station", "split", "target"):
            return getattr(self, name)
        if name == "pose":
            return self.pose_id or None
        return self.columns.get(name)

    def subset(self, idx) -> "PoseTable":
        """The rows ``idx`` (an index array or a boolean mask), every per-row field kept."""
        idx = np.flatnonzero(idx) if np.asarray(idx).dtype == bool else np.asarray(idx, int)

        def pick(v):
            if v is None:
                return None
            if isinstance(v, np.ndarray):
                return v[idx]
            return [v[i] for i in idx] if v else v
        out = PoseTable(q_rad=self.q_rad[idx], source=self.source, ignored_columns=self.ignored_columns,
                        direction_note=self.direction_note)
        for name in ("points_mm", "pose_id", "time_s", "payload_kg", "temperature_c", "direction", "sigma_mm",
                     "readings", "target", "split", "station", "polar", "orientation_rad", "line", "cov_mm2"):
            setattr(out, name, pick(getattr(self, name)))
        out.columns = {k: pick(v) for k, v in self.columns.items()}
        return out

    def split_mask(self, which: str) -> np.ndarray:
        """Boolean rows of ``fit`` or ``test`` (all rows count as both when the file has no split)."""
        if self.split is None:
            return np.ones(self.n, bool)
        return np.array([s == which for s in self.split])


# -- reading ----------------------------------------------------------------------------------------------------
def _read_lines(path: Path) -> tuple[str, list[tuple[int, str]], dict[str, str]]:
    src = str(path)
    text = read_text(path)  # UTF-8 with or without a BOM; binary or another encoding: one line
    units, lines = {}, []
    for i, ln in enumerate(text.splitlines(), 1):
        m = _UNIT_LINE.match(ln)
        if m:
            units[m.group(1)] = (m.group(2), i)
        elif ln.strip() and not ln.lstrip().startswith("#"):
            lines.append((i, ln))
    return src, lines, units


def _unit(src: str, kind: str, table: dict, file_units: dict, given: str | None) -> float:
    """Scale to internal units of the file's angle or length unit (command option and file must agree)."""
    declared = file_units.get(kind)
    if declared is not None:
        name, line = declared
        if name not in table:
            raise RobocalError(f"{src}: line {line}: {kind} {name!r} is not one of {', '.join(table)}")
        if given is not None and given != name:
            raise RobocalError(f"{src}: line {line}: the file declares {kind} {name}, the command says {given}")
        return table[name]
    if given is not None and given not in table:
        raise RobocalError(f"--{kind.replace('_', '-')}: {given!r} is not one of {', '.join(table)}")
    return table[given or ("deg" if kind == "angle_unit" else "mm")]


class _Rows:
    """The data rows with their line numbers and the number parser that names file, line and column."""

    def __init__(self, src: str, cols: list[str], rows: list[tuple[int, list[str]]]):
        self.src, self.rows = src, rows
        self.idx = {c: i for i, c in enumerate(cols)}

    def text(self, col: str) -> list[str]:
        return [v[self.idx[col]] for _, v in self.rows]

    def num(self, lineno, vals, col, lo=-math.inf, hi=math.inf, blank_ok=False) -> float:
        text = vals[self.idx[col]]
        if blank_ok and text == "":
            return math.nan
        try:
            v = float(text)
        except ValueError:
            raise RobocalError(f"{self.src}: line {lineno}: column {col}: {text!r} is not a number") from None
        if not math.isfinite(v):
            raise RobocalError(f"{self.src}: line {lineno}: column {col}: {text!r} is not finite")
        if not lo <= v <= hi:
            raise RobocalError(f"{self.src}: line {lineno}: column {col}: {v:g} is out of range [{lo:g}, {hi:g}]")
        return v

    def column(self, col, lo=-math.inf, hi=math.inf, blank_ok=False) -> np.ndarray:
        return np.array([self.num(ln, v, col, lo, hi, blank_ok) for ln, v in self.rows])


def _joint_columns(src, header_line, cols, n_joints, robot) -> tuple[list[str], np.ndarray]:
    """The reading columns and which of them are prismatic."""
    if robot is not None:
        names = list(robot.reading_names)
        pris = np.asarray(robot.reading_prismatic, bool)
        if any(c in names for c in cols):
            missing = [c for c in names if c not in cols]
            if missing:
                raise RobocalError(f"{src}: line {header_line}: missing joint column {missing[0]} (the description "
                                   f"{robot.source} reads {', '.join(names)})")
            stray = [c for c in cols if c not in names and (c.endswith("joint") or re.fullmatch(r"q\d+", c))]
            if stray:
                raise RobocalError(f"{src}: line {header_line}: column {stray[0]} is not a joint of the description "
                                   f"{robot.source} (its joints: {', '.join(names)})")
            return names, pris
        foreign = [c for c in cols if c.endswith("joint") and c not in names]
        if foreign and robot.description_joint_names:
            raise RobocalError(f"{src}: line {header_line}: column {foreign[0]} is not a joint of the description "
                               f"{robot.source} (its joints: {', '.join(names)}): data of another robot?")
        n_joints = robot.n_readings
        return [f"q{j}" for j in range(1, n_joints + 1)], pris
    qcols = [f"q{j}" for j in range(1, n_joints + 1)]
    return qcols, np.zeros(n_joints, bool)


def _wide_targets(cols: list[str]) -> list[str]:
    """Suffixes T with all of xT, yT, zT in the header (several tool points per row)."""
    out = []
    for c in cols:
        if len(c) > 1 and c[0] == "x" and f"y{c[1:]}" in cols and f"z{c[1:]}" in cols and c[1:] not in ("", "_deg"):
            out.append(c[1:])
    return out


def read_pose_csv(path: str | Path, n_joints: int = 6, prismatic=None, *, robot=None,
                  angle_unit: str | None = None, length_unit: str | None = None, order: str = "none",
                  time_column: str | None = None, direction_threshold: tuple[float, float] | None = None) -> PoseTable:
    """Read a pose CSV; raise RobocalError naming file, line and column for anything malformed.

    ``prismatic`` (bool per joint, e.g. ``robot.prismatic``): those joints are given in the length unit.  With
    ``robot`` (a :class:`calib.robot.Robot`) the joint columns may carry its reading names, reading conventions turn
    readings into joint variables, and ``target`` names are checked against its tool points.  ``order``,
    ``time_column`` and ``direction_threshold`` (rad, mm): approach directions from the measurement order
    (:mod:`calib.approach`; default: none inferred)."""
    path = Path(path)
    src, lines, file_units = _read_lines(path)
    if not lines:
        raise RobocalError(f"{src}: no header row")
    ascale = _unit(src, "angle_unit", ANGLE_UNITS, file_units, angle_unit)
    lscale = _unit(src, "length_unit", LENGTH_UNITS, file_units, length_unit)
    header_line, header = lines[0]
    cols = [c.strip() for c in csv_fields(header, src, header_line)]
    dupes = {c for c in cols if cols.count(c) > 1}
    if dupes:
        raise RobocalError(f"{src}: line {header_line}: column {sorted(dupes)[0]} appears twice")
    qcols, pris = _joint_columns(src, header_line, cols, n_joints, robot)
    if robot is None and prismatic is not None:
        pris = np.asarray(prismatic, bool)
    missing = [c for c in qcols if c not in cols]
    if missing:
        raise RobocalError(f"{src}: line {header_line}: missing column {missing[0]} (need {', '.join(qcols)})")
    xyz = [c in cols for c in ("x", "y", "z")]
    if any(xyz) and not all(xyz):
        raise RobocalError(f"{src}: line {header_line}: give all of x, y, z or none")
    wide = [] if all(xyz) else _wide_targets(cols)
    n_dir = len(qcols) if robot is None else robot.n
    known = set(qcols) | FIXED_COLUMNS | {f"dir{j}" for j in range(1, n_dir + 1)}
    known |= {f"{a}{t}" for t in wide for a in "xyz"}
    ignored = [c for c in cols if c not in known]
    rows = []
    for lineno, raw in lines[1:]:
        vals = csv_fields(raw, src, lineno)
        if len(vals) != len(cols):
            raise RobocalError(f"{src}: line {lineno}: {len(vals)} fields, the header has {len(cols)}")
        rows.append((lineno, [v.strip() for v in vals]))
    if not rows:
        raise RobocalError(f"{src}: no pose rows after the header")
    R = _Rows(src, cols, rows)
    lim = [(-1e6, 1e6) if p else (-720 * DEG / ascale, 720 * DEG / ascale) for p in pris]
    readings = np.array([[R.num(ln, v, c, *lim[j]) for j, c in enumerate(qcols)] for ln, v in rows])
    readings = readings * np.where(pris, lscale, ascale)
    q = robot.joints_from_readings(readings) if robot is not None else readings
    table = PoseTable(q_rad=q, source=src, ignored_columns=ignored, readings=readings,
                      line=[ln for ln, _ in rows])
    table.columns = {c: R.text(c) for c in ignored}
    _labels(table, R, robot, cols, header_line)
    if all(xyz):
        table.points_mm = np.column_stack([R.column(c) for c in "xyz"]) * lscale
    _sigma(table, R, cols, header_line, all(xyz))
    _instrument(table, R, cols, header_line, lscale)
    for col, (attr, lo, hi) in CONDITION_COLUMNS.items():
        if col in R.idx:
            setattr(table, attr, R.column(col, lo, hi))
    _directions(table, R, n_dir)
    _measurement_order(table, R, cols, header_line, robot.prismatic if robot is not None else pris, order,
                       time_column, direction_threshold)
    if wide:
        table = _expand_targets(table, R, wide, robot, lscale, header_line)
    _check_poses(table)
    if robot is not None and robot.is_tree:
        frames = {robot.point_frame(k) for k in robot.tool_points_mm}
        if table.points_mm is not None and table.target is None and len(frames) > 1:
            raise RobocalError(f"{src}: line {header_line}: {robot.source} has points on several links "
                               f"({', '.join(robot.tool_points_mm)}): a target column must say which one each row "
                               "measures")
        _check_shared_joints(table, robot, qcols, pris, ascale, lscale)
    if table.ignored_columns:
        warnings.warn(f"{src}: ignoring unknown column(s) {', '.join(table.ignored_columns)}", stacklevel=2)
    return table


def _labels(table: PoseTable, R: _Rows, robot, cols, header_line) -> None:
    src = R.src
    if "pose" in R.idx:
        table.pose_id = R.text("pose")
    if "station" in R.idx:
        table.station = R.text("station")
    if "split" in R.idx:
        split = R.text("split")
        for (ln, _), s in zip(R.rows, split):
            if s not in SPLITS:
                raise RobocalError(f"{src}: line {ln}: column split: {s!r} must be fit or test")
        table.split = split
    if "target" in R.idx:
        target = R.text("target")
        if robot is not None:
            for (ln, _), t in zip(R.rows, target):
                if t not in robot.tool_points_mm:
                    known = ", ".join(robot.tool_points_mm) or "none"
                    raise RobocalError(f"{src}: line {ln}: column target: {t!r} names no tool point of "
                                       f"{robot.source} (tool points: {known})")
        table.target = target


def _sigma(table: PoseTable, R: _Rows, cols, header_line, has_xyz) -> None:
    scols = ("sigma_x_mm", "sigma_y_mm", "sigma_z_mm")
    if any(c in R.idx for c in scols):
        if not all(c in R.idx for c in scols) or not has_xyz:
            raise RobocalError(f"{R.src}: line {header_line}: sigma_x_mm, sigma_y_mm, sigma_z_mm go together, "
                               "with x, y, z")
        table.sigma_mm = np.column_stack([R.column(c, 1e-9, 1e6) for c in scols])


def _instrument(table: PoseTable, R: _Rows, cols, header_line, lscale) -> None:
    """Polar readings (hz_deg, v_deg, dist_mm) and measured orientations (rx_deg, ry_deg, rz_deg)."""
    for group, attr in ((("hz_deg", "v_deg", "dist_mm"), "polar"), (("rx_deg", "ry_deg", "rz_deg"),
                                                                    "orientation_rad")):
        present = [c in R.idx for c in group]
        if any(present) and not all(present):
            raise RobocalError(f"{R.src}: line {header_line}: {', '.join(group)} go together")
        if all(present):
            arr = np.column_stack([R.column(c) for c in group])
            arr[:, :2 if attr == "polar" else 3] *= DEG
            if attr == "polar":
                bad = np.flatnonzero(arr[:, 2] <= 0)
                if bad.size:
                    raise RobocalError(f"{R.src}: line {table.line[bad[0]]}: column dist_mm: must be positive")
            setattr(table, attr, arr)


def _directions(table: PoseTable, R: _Rows, n: int) -> None:
    dcols = [f"dir{j}" for j in range(1, n + 1)]
    if any(c in R.idx for c in dcols):
        d = np.zeros((len(R.rows), n))
        for j, c in enumerate(dcols):
            if c in R.idx:
                for r, (ln, v) in enumerate(R.rows):
                    val = R.num(ln, v, c)
                    if val not in (-1.0, 1.0, 0.0):
                        raise RobocalError(f"{R.src}: line {ln}: column {c}: must be +1 or -1, got {val:g}")
                    d[r, j] = val
        table.direction = d


def _measurement_order(table: PoseTable, R: _Rows, cols, header_line, prismatic, order, time_column,
                       threshold) -> None:
    """The time column (``--time-column`` or a recognised name) as the rows' time, and the approach directions
    inferred from the measurement order when ``order`` asks for them (:func:`calib.approach.infer`)."""
    tcol = find_time_column(cols, time_column, R.src, header_line) if (order != "none" or time_column) else None
    if tcol is not None and tcol != "time":
        t = R.column(tcol)
        if table.time_s is None:
            table.time_s = t
        table.ignored_columns = [c for c in table.ignored_columns if c != tcol]
        table.columns.pop(tcol, None)
    thr_rad, thr_mm = threshold if threshold is not None else (None, None)
    inf = infer(table.q_rad, prismatic, order, has_dir=table.direction is not None, time_col=tcol,
                time_s=R.column(tcol) if tcol is not None else None, lines=table.line, src=R.src,
                threshold_rad=thr_rad, threshold_mm=thr_mm)
    if inf is not None:
        table.direction = inf.direction
        table.direction_note = inf.note()


def _expand_targets(table: PoseTable, R: _Rows, wide: list[str], robot, lscale, header_line) -> PoseTable:
    """One row per (row, target) from x<T>, y<T>, z<T> columns; blank cells mean the target was not seen."""
    if robot is not None:
        unknown = [t for t in wide if t not in robot.tool_points_mm]
        wide = [t for t in wide if t in robot.tool_points_mm]
        if unknown:
            table.ignored_columns += [f"{a}{t}" for t in unknown for a in "xyz"]
        if not wide:
            known = ", ".join(robot.tool_points_mm) or "none"
            raise RobocalError(f"{R.src}: line {header_line}: the target columns ({', '.join(unknown)}) name no tool "
                               f"point of {robot.source} (tool points: {known})")
    if not table.pose_id:
        table.pose_id = [str(ln) for ln in table.line]
    rows, pts, tgt = [], [], []
    for t in wide:
        p = np.column_stack([R.column(f"{a}{t}", blank_ok=True) for a in "xyz"]) * lscale
        seen = np.isfinite(p).all(axis=1)
        part = np.isfinite(p).any(axis=1) & ~seen
        if part.any():
            raise RobocalError(f"{R.src}: line {table.line[np.flatnonzero(part)[0]]}: target {t}: give all of x{t}, "
                               f"y{t}, z{t} or none")
        rows += list(np.flatnonzero(seen))
        pts.append(p[seen])
        tgt += [t] * int(seen.sum())
    order = np.argsort(np.array(rows), kind="stable")
    out = table.subset(np.array(rows, int)[order])
    out.points_mm = np.concatenate(pts)[order]
    out.target = [tgt[i] for i in order]
    return out


def _check_poses(table: PoseTable) -> None:
    """Rows of one pose share their split and station."""
    if not table.pose_id:
        return
    for attr in ("split", "station"):
        labels = getattr(table, attr)
        if labels is None:
            continue
        first: dict[str, str] = {}
        for pid, lab, ln in zip(table.pose_id, labels, table.line):
            if first.setdefault(pid, lab) != lab:
                raise RobocalError(f"{table.source}: line {ln}: pose {pid!r} is {first[pid]!r} on an earlier row "
                                   f"and {lab!r} here (column {attr})")


#: readings of one pose that two targets' rows may differ by (deg, mm): an encoder's noise, not another pose
SHARED_READING_TOLERANCE = 0.01


def _check_shared_joints(table: PoseTable, robot, qcols: list[str], pris, ascale: float, lscale: float) -> None:
    """On a branched robot, rows of one pose measuring targets on different branches must agree on every joint both
    targets hang from (a torso under two arms): a contradiction is one error naming both lines."""
    if not table.pose_id or table.target is None:
        return
    A = robot.frame_ancestors()
    moves = np.zeros((robot.n_readings, robot.n + 1), bool)         # reading c moves frame f
    for k in range(robot.n):
        for c in np.flatnonzero(robot.reading_matrix[k]):
            moves[c] |= A[:, k + 1]
    tol = SHARED_READING_TOLERANCE * np.where(pris, lscale, DEG)
    first: dict[str, int] = {}
    for i, pid in enumerate(table.pose_id):
        j = first.setdefault(pid, i)
        if j == i:
            continue
        fi, fj = robot.point_frame(table.target[i]), robot.point_frame(table.target[j])
        shared = moves[:, fi] & moves[:, fj]
        bad = np.flatnonzero(shared & (np.abs(table.readings[i] - table.readings[j]) > tol))
        if bad.size:
            c = int(bad[0])
            unit, scale = ("mm", lscale) if pris[c] else ("deg", DEG)
            raise RobocalError(f"{table.source}: line {table.line[i]}: pose {pid!r}: column {qcols[c]} reads "
                               f"{table.readings[i, c] / scale:g} {unit} here but {table.readings[j, c] / scale:g} "
                               f"{unit} on line {table.line[j]}: both targets hang from that joint, so one pose "
                               "reads it once")


def raw_rows(path: str | Path) -> dict[int, dict[str, str]]:
    """Every data row of a pose CSV exactly as written, by source line: column -> text (unit comment lines and
    comments left out).  Why: an import keeps what the operator measured, columns robocal does not use included."""
    src, lines, _ = _read_lines(Path(path))
    if not lines:
        return {}
    cols = [c.strip() for c in csv_fields(lines[0][1], src, lines[0][0])]
    return {ln: dict(zip(cols, (v.strip() for v in csv_fields(raw, src, ln)))) for ln, raw in lines[1:]}


def csv_fields(line: str, src: str, lineno: int) -> list[str]:
    """The fields of one CSV line; a malformed line (a field over the csv module's 128 KiB limit, a stray quote)
    is one error naming the file and the line."""
    try:
        return next(csv.reader([line], strict=True), [])
    except csv.Error as exc:
        raise RobocalError(f"{src}: line {lineno}: not a CSV row: {exc}") from None


def write_pose_csv(path: str | Path, q_rad: np.ndarray, points_mm: np.ndarray | None = None,
                   extra: dict[str, np.ndarray] | None = None, prismatic=None,
                   labels: dict[str, list[str]] | None = None, names=None) -> None:
    """Write poses (and optionally points, extra number columns and ``labels``: text columns such as pose, station,
    split, target) in the pose CSV format, angles in degrees (prismatic joints in mm); ``names``: the joint
    columns' names (a description's readings; default q1..qn)."""
    q = np.atleast_2d(q_rad)
    if prismatic is not None:
        q = q / np.where(np.asarray(prismatic, bool), 1.0, DEG) * DEG
    n = q.shape[1]
    cols = list(names) if names is not None else [f"q{j}" for j in range(1, n + 1)]
    data = [q / DEG]
    if points_mm is not None:
        cols += ["x", "y", "z"]
        data.append(points_mm)
    for k, v in (extra or {}).items():
        cols.append(k)
        data.append(np.asarray(v, float).reshape(len(q), -1))
    arr = np.hstack(data)
    fh = io.StringIO(newline="")
    w = csv.writer(fh)
    labels = labels or {}
    w.writerow(cols + list(labels))
    for i, row in enumerate(arr):
        w.writerow([f"{v:.6f}" for v in row] + [str(v[i]) for v in labels.values()])
    atomic_write_text(path, fh.getvalue())
