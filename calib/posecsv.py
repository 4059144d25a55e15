"""The pose-measurement CSV: joint readings and, optionally, measured tool-target positions and pose conditions.

Format (shared by ``robocal plan``, ``robocal import`` and ``robocal diagnose``): a header row, then one row per pose.
Lines starting with ``#`` are comments.

========================  ===============================================================================
column                    meaning
========================  ===============================================================================
``q1`` .. ``qn``          joint readings in degrees (convention of the robot description), required
``x``, ``y``, ``z``       tool-target position in mm in the instrument frame (all three, or none)
``pose``                  pose id (text)
``time``                  s
``payload``               kg
``temperature``           deg C
``dir1`` .. ``dirn``      +1 / -1: the sign of each joint's last motion before the pose was reached
``sigma_x_mm`` ..         1-sigma uncertainty of x, y, z (mm), when the instrument model is known (robocal's
``sigma_z_mm``            extension; other readers ignore them)
========================  ===============================================================================

Unknown columns are ignored with a warning; a malformed row is an error naming the file, the line and the column.
"""
from __future__ import annotations

import csv
import io
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import RobocalError
from .fileio import atomic_write_text
from .units import DEG


@dataclass
class PoseTable:
    q_rad: np.ndarray                         # (N, n)
    points_mm: np.ndarray | None = None       # (N, 3)
    pose_id: list[str] = field(default_factory=list)
    time_s: np.ndarray | None = None
    payload_kg: np.ndarray | None = None
    temperature_c: np.ndarray | None = None
    direction: np.ndarray | None = None       # (N, n)
    sigma_mm: np.ndarray | None = None        # (N, 3)
    source: str = "<memory>"
    ignored_columns: list[str] = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.q_rad)


def read_pose_csv(path: str | Path, n_joints: int = 6, prismatic=None) -> PoseTable:
    """Read a pose CSV; raise RobocalError naming file, line and column for anything malformed.

    ``prismatic`` (bool per joint, e.g. ``robot.prismatic``): those joints are given in mm, not degrees."""
    path = Path(path)
    src = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise RobocalError(f"{src}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RobocalError(f"{src}: cannot read: {exc}") from None
    lines = [(i, ln) for i, ln in enumerate(text.splitlines(), 1) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise RobocalError(f"{src}: no header row")
    header_line, header = lines[0]
    cols = [c.strip() for c in next(csv.reader([header]))]
    qcols = [f"q{j}" for j in range(1, n_joints + 1)]
    missing = [c for c in qcols if c not in cols]
    if missing:
        raise RobocalError(f"{src}: line {header_line}: missing column {missing[0]} (need {', '.join(qcols)})")
    xyz = [c in cols for c in ("x", "y", "z")]
    if any(xyz) and not all(xyz):
        raise RobocalError(f"{src}: line {header_line}: give all of x, y, z or none")
    known = set(qcols) | {"x", "y", "z", "pose", "time", "payload", "temperature", "sigma_x_mm", "sigma_y_mm",
                          "sigma_z_mm"} | \
        {f"dir{j}" for j in range(1, n_joints + 1)}
    ignored = [c for c in cols if c not in known]
    if ignored:
        warnings.warn(f"{src}: ignoring unknown column(s) {', '.join(ignored)}", stacklevel=2)
    dupes = {c for c in cols if cols.count(c) > 1}
    if dupes:
        raise RobocalError(f"{src}: line {header_line}: column {sorted(dupes)[0]} appears twice")
    idx = {c: i for i, c in enumerate(cols)}
    rows = []
    for lineno, raw in lines[1:]:
        vals = next(csv.reader([raw]))
        if len(vals) != len(cols):
            raise RobocalError(f"{src}: line {lineno}: {len(vals)} fields, the header has {len(cols)}")
        rows.append((lineno, [v.strip() for v in vals]))
    if not rows:
        raise RobocalError(f"{src}: no pose rows after the header")

    def num(lineno, vals, col, lo=-math.inf, hi=math.inf):
        text = vals[idx[col]]
        try:
            v = float(text)
        except ValueError:
            raise RobocalError(f"{src}: line {lineno}: column {col}: {text!r} is not a number") from None
        if not math.isfinite(v):
            raise RobocalError(f"{src}: line {lineno}: column {col}: {text!r} is not finite")
        if not lo <= v <= hi:
            raise RobocalError(f"{src}: line {lineno}: column {col}: {v:g} is out of range [{lo:g}, {hi:g}]")
        return v

    pris = np.zeros(n_joints, bool) if prismatic is None else np.asarray(prismatic, bool)
    lim = [(-1e6, 1e6) if p else (-720, 720) for p in pris]
    q = np.array([[num(ln, v, c, *lim[j]) for j, c in enumerate(qcols)] for ln, v in rows])
    q = q * np.where(pris, 1.0, DEG)
    table = PoseTable(q_rad=q, source=src, ignored_columns=ignored)
    if all(xyz):
        table.points_mm = np.array([[num(ln, v, c) for c in ("x", "y", "z")] for ln, v in rows])
    scols = ("sigma_x_mm", "sigma_y_mm", "sigma_z_mm")
    if any(c in idx for c in scols):
        if not all(c in idx for c in scols) or not all(xyz):
            raise RobocalError(f"{src}: line {header_line}: sigma_x_mm, sigma_y_mm, sigma_z_mm go together, with x, y, z")
        table.sigma_mm = np.array([[num(ln, v, c, 1e-9, 1e6) for c in scols] for ln, v in rows])
    if "pose" in idx:
        table.pose_id = [v[idx["pose"]] for _, v in rows]
    for col, attr, lo, hi in (("time", "time_s", -math.inf, math.inf), ("payload", "payload_kg", 0, 1e4),
                              ("temperature", "temperature_c", -100, 200)):
        if col in idx:
            setattr(table, attr, np.array([num(ln, v, col, lo, hi) for ln, v in rows]))
    dcols = [f"dir{j}" for j in range(1, n_joints + 1)]
    if any(c in idx for c in dcols):
        d = np.zeros((len(rows), n_joints))
        for j, c in enumerate(dcols):
            if c in idx:
                for r, (ln, v) in enumerate(rows):
                    val = num(ln, v, c)
                    if val not in (-1.0, 1.0, 0.0):
                        raise RobocalError(f"{src}: line {ln}: column {c}: must be +1 or -1, got {val:g}")
                    d[r, j] = val
        table.direction = d
    return table


def write_pose_csv(path: str | Path, q_rad: np.ndarray, points_mm: np.ndarray | None = None,
                   extra: dict[str, np.ndarray] | None = None, prismatic=None) -> None:
    """Write poses (and optionally points and extra columns) in the pose CSV format, angles in degrees (prismatic
    joints in mm)."""
    q = np.atleast_2d(q_rad)
    if prismatic is not None:
        q = q / np.where(np.asarray(prismatic, bool), 1.0, DEG) * DEG
    n = q.shape[1]
    cols = [f"q{j}" for j in range(1, n + 1)]
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
    w.writerow(cols)
    for row in arr:
        w.writerow([f"{v:.6f}" for v in row])
    atomic_write_text(path, fh.getvalue())
