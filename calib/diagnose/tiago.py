"""Loader for a public real-robot data set: the TIAGo arm Qualisys mocap file from FIGAROH's examples.

``qualysis_base_hand_calibration.csv`` (figaroh-examples, examples/tiago/data/calibration/mocap; Apache-2.0): a header,
then one row per static posture: ``x1,y1,z1 .. x4,y4,z4`` four points of the tracked hand body in metres, expressed
in a mocap rigid body fixed to the robot base, then ``torso_lift_joint`` (m) and ``arm_1_joint .. arm_7_joint`` (rad).
FIGAROH uses point 1 as a point fixed to the hand, position only; so do we (the tool point of
``calib/data/tiago_arm.toml``).  The conversion here is only units (m -> mm) and column order; the robot description
turns the eight joint values into the chain.

What the file cannot carry: no per-point uncertainty (so ``--noise-mm`` is required), no approach directions, no
time, temperature or payload — so only the geometric gap and the effects driven by joint angles and gravity can be
examined.  The figaroh-examples data README also says that this file is superseded: joints and markers were paired by
raw timestamps with a 3.9 s clock offset uncorrected, so 16 of the 34 rows hold a marker sample taken while the arm
was already moving (errors up to 7.8 mm).
"""
from __future__ import annotations

import csv
from importlib import resources
from pathlib import Path

import numpy as np

from calib.errors import RobocalError
from calib.robot import Robot, parse_robot

JOINT_COLUMNS = ["torso_lift_joint"] + [f"arm_{k}_joint" for k in range(1, 8)]
POINT_COLUMNS = ["x1", "y1", "z1"]


def tiago_robot() -> Robot:
    """The shipped TIAGo torso + arm description (calib/data/tiago_arm.toml)."""
    ref = resources.files("calib") / "data" / "tiago_arm.toml"
    return parse_robot(ref.read_text(encoding="utf-8"), "tiago_arm.toml")


def _header(path: Path) -> list[str]:
    try:
        with open(path, encoding="utf-8", newline="") as fh:
            for line in fh:
                if line.strip() and not line.lstrip().startswith("#"):
                    return [c.strip() for c in next(csv.reader([line]))]
    except (OSError, UnicodeDecodeError):
        return []
    return []


def is_tiago_mocap(path: str | Path) -> bool:
    """True when the header is the FIGAROH TIAGo mocap layout (marker columns and TIAGo joint names)."""
    cols = _header(Path(path))
    return all(c in cols for c in POINT_COLUMNS + JOINT_COLUMNS)


def read_tiago_mocap(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(q (N, 8): torso lift in mm then arm joints in rad, marker-1 points (N, 3) in mm); errors name file and line."""
    path = Path(path)
    src = str(path)
    try:
        rows = list(csv.reader(path.read_text(encoding="utf-8").splitlines()))
    except (OSError, UnicodeDecodeError) as exc:
        raise RobocalError(f"{src}: cannot read: {exc}") from None
    header = [c.strip() for c in rows[0]] if rows else []
    missing = [c for c in POINT_COLUMNS + JOINT_COLUMNS if c not in header]
    if missing:
        raise RobocalError(f"{src}: line 1: missing column {missing[0]} (TIAGo mocap layout)")
    idx = {c: header.index(c) for c in POINT_COLUMNS + JOINT_COLUMNS}
    q, p = [], []
    for lineno, row in enumerate(rows[1:], 2):
        if not row or not "".join(row).strip():
            continue
        if len(row) != len(header):
            raise RobocalError(f"{src}: line {lineno}: {len(row)} fields, the header has {len(header)}")
        vals = {}
        for c, i in idx.items():
            try:
                v = float(row[i])
            except ValueError:
                raise RobocalError(f"{src}: line {lineno}: column {c}: {row[i]!r} is not a number") from None
            if not np.isfinite(v):
                raise RobocalError(f"{src}: line {lineno}: column {c}: {row[i]!r} is not finite")
            vals[c] = v
        q.append([vals["torso_lift_joint"] * 1000.0] + [vals[c] for c in JOINT_COLUMNS[1:]])
        p.append([vals[c] * 1000.0 for c in POINT_COLUMNS])
    if not q:
        raise RobocalError(f"{src}: no data rows after the header")
    return np.array(q), np.array(p)


def load_tiago_mocap(path: str | Path, robot: Robot | None = None, noise_mm: float | None = None):
    """The mocap file as :class:`calib.diagnose.data.DiagnosisData` with the TIAGo description."""
    from .data import from_arrays

    robot = robot or tiago_robot()
    if robot.n != 8:
        raise RobocalError(f"{path}: the TIAGo mocap file has 8 joints (torso lift + arm_1..7); the robot "
                           f"description {robot.source} has {robot.n}")
    q, p = read_tiago_mocap(path)
    d = from_arrays(robot, q, p, None, noise_mm, source=str(path))
    d.notes.append("TIAGo mocap file: marker 1 used as the tool point; no directions, time, temperature or payload")
    return d
