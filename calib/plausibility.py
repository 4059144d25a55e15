"""Plausibility of data and fit: catch the file that says nothing about its units before it gives a wrong number.

A fit always "works": points in metres identify with a residual of 0.0002 mm, angles in radians with a residual of
795 mm, thirty copies of one pose with a held-out RMS of 0.  These checks compare the data with what the robot
description predicts and the fit with the stated noise:

- ``length_unit`` / ``angle_unit``: the spread of the measured points (RMS distance from their centroid, which no
  base pose changes) against the spread the description predicts for the same joint readings.  A ratio near 1e-3
  means metres; a much larger one with every revolute reading inside +-2 pi means radians read as degrees.
- ``joint_count``: the data has joint columns the description does not have.
- ``distinct_poses``: fewer distinct poses than the estimated parameters need (three equations per pose).
- ``chi_square``: a reduced chi-square far below 1 (noise overstated, or metres) or absurdly large (units, or a wrong
  description).

Each finding is an error (one line, exit 2); with ``force`` it becomes a named warning on stderr and in the JSON.
"""
from __future__ import annotations

import re
import sys
from dataclasses import dataclass

import numpy as np

from .errors import RobocalError

#: the measured/predicted spread ratio outside which the units are taken to be wrong
SPREAD_RATIO = (1 / 3, 3.0)
#: a reduced chi-square outside this range cannot come from the stated noise and a right description
CHI2_RANGE = (1e-3, 1e5)


@dataclass(frozen=True)
class Finding:
    """One implausibility: ``code`` names the check (stable, for the JSON), ``message`` says what and what to do."""

    code: str
    message: str

    def to_json(self) -> dict:
        return {"code": self.code, "message": self.message}


def _spread(p: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1))))


def distinct_poses(q: np.ndarray, tol: float = 1e-6, target=None) -> int:
    """Number of distinct rows of joint readings (to ``tol``); with ``target`` (the point each row measures),
    of distinct (readings, point) pairs: each gives three equations."""
    key = np.round(np.asarray(q) / tol).astype(np.int64)
    if target is not None:
        ids = {t: i for i, t in enumerate(dict.fromkeys(target))}
        key = np.column_stack([key, [ids[t] for t in target]])
    return len(np.unique(key, axis=0))


def check_data(model, q: np.ndarray, points_mm: np.ndarray, source: str, *, n_free: int | None = None,
               ignored_columns=(), prismatic=None, target=None) -> list[Finding]:
    """Findings on the data before a fit (see the module docstring); ``model`` is the nominal MeasurementModel."""
    out: list[Finding] = []
    n = model.robot.n
    extra = [c for c in ignored_columns if re.fullmatch(r"q\d+", str(c)) and int(str(c)[1:]) > n]
    if extra:
        out.append(Finding("joint_count", f"{source}: the data has joint column(s) {', '.join(extra)} but the "
                                          f"description {model.robot.source} has {n} joints"))
    q = np.asarray(q, float)
    k = distinct_poses(q)
    m = distinct_poses(q, target=target) if target is not None else k      # several points a pose: more equations
    if n_free is not None and 3 * m <= n_free:
        what = f"{k} distinct pose(s)" if m == k else f"{k} distinct pose(s) ({m} measured points)"
        out.append(Finding("distinct_poses", f"{source}: {what} give {3 * m} equations for {n_free} "
                                             f"parameters: measure more, different poses"))
    with np.errstate(all="ignore"):
        predicted = _spread(model.points(q))
    measured = _spread(np.asarray(points_mm, float))
    if k >= 3 and predicted > 1.0:
        ratio = measured / predicted
        pris = np.zeros(q.shape[1], bool) if prismatic is None else np.asarray(prismatic, bool)
        revolute = q[:, ~pris] if (~pris).any() else q[:, :0]
        looks_rad = revolute.size > 0 and np.abs(revolute).max() <= 2 * np.pi * np.pi / 180 * 1.01
        if ratio < SPREAD_RATIO[0]:
            hint = " -- in metres? (say --length-unit m)" if ratio < 0.01 else ""
            out.append(Finding("length_unit", f"{source}: the measured points spread {measured:.4g} mm, the "
                                              f"description predicts {predicted:.4g} mm for these joint readings"
                                              f"{hint}"))
        elif ratio > SPREAD_RATIO[1]:
            hint = (" -- joint angles in radians? (say --angle-unit rad)" if looks_rad
                    else " -- check the units and the description")
            out.append(Finding("angle_unit" if looks_rad else "length_unit",
                               f"{source}: the measured points spread {measured:.4g} mm, the description predicts "
                               f"{predicted:.4g} mm for these joint readings{hint}"))
    return out


def check_fit(reduced_chi2: float, source: str, dof: int | None = None) -> list[Finding]:
    """Findings on a finished fit: a reduced chi-square the stated noise cannot give."""
    if dof is not None and dof <= 0:
        return []
    if not np.isfinite(reduced_chi2):
        return [Finding("chi_square", f"{source}: the fit's reduced chi-square is {reduced_chi2}")]
    lo, hi = CHI2_RANGE
    if reduced_chi2 < lo:
        return [Finding("chi_square", f"{source}: reduced chi-square {reduced_chi2:.3g} is impossibly small: the "
                                      "noise is overstated (--noise-mm) or the points are not in mm")]
    if reduced_chi2 > hi:
        return [Finding("chi_square", f"{source}: reduced chi-square {reduced_chi2:.3g} is impossibly large: wrong "
                                      "units, a wrong description, or a noise far below the real one (--noise-mm)")]
    return []


def enforce(findings: list[Finding], force: bool, command: str) -> list[dict]:
    """Raise the first finding as an error, or (``force``) print each as a named warning; the JSON list."""
    if findings and not force:
        raise RobocalError(f"{findings[0].message} (implausible data, check '{findings[0].code}'; "
                           f"--force-implausible runs anyway)")
    for f in findings:
        print(f"robocal: warning: {command}: implausible data ({f.code}): {f.message}", file=sys.stderr)
    return [f.to_json() for f in findings]
