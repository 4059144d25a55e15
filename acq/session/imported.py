"""Pose measurements imported from a pose CSV, as session steps and back.

Why one module: ``robocal import`` writes every measured quantity of a pose-CSV row into its ``poses`` step, and
reprocessing and the diagnosis read them back; keeping the writer and the readers together keeps them in step.

A step keeps

* operator inputs (numbers with their unit): ``x_mm``, ``y_mm``, ``z_mm``; ``sigma_x_mm`` .. ``sigma_z_mm`` when the
  file gives them; ``time_s``, ``payload_kg``, ``temperature_c`` and ``dir1`` .. ``dirn`` when the file has them;
* ``spec["imported"]``: the source file and line, the row's labels (``pose``, ``station``, ``split``, ``target``)
  and the whole row as written (every column, those robocal does not read included): nothing measured is lost.

Sessions imported before the sigma columns were kept have only x, y, z: their points get
:data:`DEFAULT_SIGMA_MM`, as then.
"""
from __future__ import annotations

import time

import numpy as np

from calib.effects import PoseContext
from calib.errors import RobocalError
from calib.units import DEG

from .store import StepRecord

#: 1-sigma per coordinate of an imported point whose file gave no sigma_x_mm.. columns (mm)
DEFAULT_SIGMA_MM = 0.05
XYZ = ("x_mm", "y_mm", "z_mm")
SIGMAS = ("sigma_x_mm", "sigma_y_mm", "sigma_z_mm")
#: PoseTable condition -> (input name, unit)
CONDITIONS = {"time_s": "s", "payload_kg": "kg", "temperature_c": "degC"}
LABELS = ("station", "split", "target")


def _input(name: str, value: float, unit: str, now: float) -> dict:
    return {"attempt": 1, "name": name, "value": float(value), "unit": unit, "t_wall_s": now}


def pose_steps(table, raw: dict[int, dict[str, str]], source: str) -> list[StepRecord]:
    """One accepted ``poses`` step per row of a :class:`calib.posecsv.PoseTable` (several targets of one pose: one
    step each, keyed ``poses/POSE/TARGET``); ``raw`` is :func:`calib.posecsv.raw_rows` of the same file."""
    now = time.time()
    out = []
    for i in range(table.n):
        pid = table.pose_id[i] if table.pose_id else f"{i:03d}"
        labels = {k: getattr(table, k)[i] for k in LABELS if getattr(table, k) is not None}
        if table.pose_id:
            labels["pose"] = pid
        ln = table.line[i] if table.line else None
        spec = {"pose_deg": (table.q_rad[i] / DEG).tolist(), "meta": {"index": i}, "targets": [], "setup": {},
                "imported": {"source": source, "line": ln, "labels": labels, "row": raw.get(ln, {})}}
        inputs = [_input(k, v, "mm", now) for k, v in zip(XYZ, table.points_mm[i])]
        if table.sigma_mm is not None:
            inputs += [_input(k, v, "mm", now) for k, v in zip(SIGMAS, table.sigma_mm[i])]
        for attr, unit in CONDITIONS.items():
            if getattr(table, attr) is not None:
                inputs.append(_input(attr, getattr(table, attr)[i], unit, now))
        if table.direction is not None:
            inputs += [_input(f"dir{j + 1}", v, "", now) for j, v in enumerate(table.direction[i])]
        key = f"poses/{pid}" + (f"/{labels['target']}" if "target" in labels else "")
        out.append(StepRecord(key, "poses", f"imported pose {pid}", "imported", "accepted", 1,
                              now, now, spec, "", [], [], inputs, []))
    return out


def imported_point(step: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """(point_mm (3,), covariance (3, 3)) of an imported pose step, None for a step without x, y, z inputs.  The
    covariance is the file's sigma_x_mm.. (an old import's ``sigma_mm``, else :data:`DEFAULT_SIGMA_MM`)."""
    inp = step["inputs"]
    if not all(inp.get(k) is not None for k in XYZ):
        return None
    p = np.array([inp[k] for k in XYZ], float)
    if all(inp.get(k) is not None for k in SIGMAS):
        return p, np.diag(np.square([inp[k] for k in SIGMAS]))
    return p, np.eye(3) * float(inp.get("sigma_mm") or DEFAULT_SIGMA_MM) ** 2


def imported_labels(steps: list[dict], name: str) -> list[str] | None:
    """Per-step label ``name`` (station, split, target, pose) of imported steps; None when a step has none."""
    vals = [(s["spec"].get("imported") or {}).get("labels", {}).get(name) for s in steps]
    return None if not vals or any(v is None for v in vals) else [str(v) for v in vals]


def imported_conditions(steps: list[dict], n_joints: int) -> dict[str, np.ndarray]:
    """What the imported steps were measured under, as :class:`PoseContext` arrays (``time_s``, ``payload_kg``,
    ``temperature_c``, ``direction``): only those every step carries."""
    out: dict[str, np.ndarray] = {}
    for attr in CONDITIONS:
        vals = [s["inputs"].get(attr) for s in steps]
        if steps and all(v is not None for v in vals):
            out[attr] = np.array(vals, float)
    dirs = [[s["inputs"].get(f"dir{j}") for j in range(1, n_joints + 1)] for s in steps]
    if steps and any(v is not None for row in dirs for v in row):
        out["direction"] = np.array([[0.0 if v is None else v for v in row] for row in dirs])
    return out


def imported_context(steps: list[dict], n_joints: int) -> PoseContext | None:
    """The :class:`PoseContext` of imported steps (None when they carry no condition)."""
    cond = imported_conditions(steps, n_joints)
    return PoseContext(len(steps), n_joints, **cond) if cond else None


def one_target_one_station(steps: list[dict], where: str) -> None:
    """Reprocessing fits one tool point seen from one instrument set-up: an imported pose set with several targets
    or stations is one line pointing to the commands that fit them, never a silently wrong fit."""
    for name, cmd in (("target", "with a description naming the tool points"),
                      ("station", "(one instrument transform per station)")):
        vals = sorted(set(imported_labels(steps, name) or []))
        if len(vals) > 1:
            raise RobocalError(f"{where}: poses: the imported rows name {len(vals)} {name}s ({', '.join(vals)}); "
                               f"reprocess fits one: run robocal identify on the pose CSV {cmd}")
