"""Findings confirmed on independent data: ``robocal diagnose DATA --confirm OTHER.csv``.

A finding made on one data set can be an accident of it (its poses, its day).  Confirmation refits nothing but the
instrument-to-base transform on OTHER (per ``station`` group: another day or set-up may have moved the base), with
the model of each step of the selection as fitted on DATA held fixed, and compares the RMS on OTHER step by step.  A
finding is confirmed when adding it shrinks the RMS on OTHER by at least the share of OTHER's excess over its noise
floor that the acceptance rule asks on DATA (:data:`calib.diagnose.select.MATERIAL_SHARE`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.errors import RobocalError
from calib.identify import identify

from .data import DiagnosisData
from .gap import CVResult, noise_floor_mm, rms_mm
from .select import MATERIAL_SHARE

BASE_PARAMS = tuple(f"base.{k}" for k in ("x_mm", "y_mm", "z_mm", "yaw_rad", "pitch_rad", "roll_rad"))
#: poses a station group needs to re-station (6 parameters, 3 observations a pose, and some to spare)
MIN_POSES_PER_STATION = 4
#: OTHER's geometric RMS above this multiple of DATA's (and above 10 mm) means another robot, not another day
NOT_THE_SAME = 50.0


@dataclass
class Confirmation:
    source: str
    n: int
    floor_mm: float
    steps: list[tuple[str, float]]        # (label, RMS on OTHER after re-stationing), the geometric model first

    def findings(self) -> list[dict]:
        excess = self.steps[0][1] - self.floor_mm
        out = []
        for (_, before), (label, after) in zip(self.steps, self.steps[1:]):
            shrink = before - after
            out.append({"label": label, "rms_before_mm": before, "rms_after_mm": after, "shrink_mm": shrink,
                        "confirmed": bool(excess > 0 and shrink >= MATERIAL_SHARE * excess)})
        return out

    def as_dict(self) -> dict:
        return {"source": self.source, "poses": self.n, "noise_floor_mm": self.floor_mm,
                "geometric_rms_mm": self.steps[0][1], "findings": self.findings()}


def _groups(other: DiagnosisData) -> list[np.ndarray]:
    st = other.labels.get("station")
    if not st:
        return [np.arange(other.n)]
    st = np.asarray(st)
    out = []
    for name in sorted({str(s) for s in st}):
        idx = np.flatnonzero(st == name)
        if len(idx) < MIN_POSES_PER_STATION:
            raise RobocalError(f"{other.source}: station {name!r} has {len(idx)} poses, fewer than the "
                               f"{MIN_POSES_PER_STATION} needed to re-station it (6 parameters)")
        out.append(idx)
    return out


def restationed_residual(fit: CVResult, other: DiagnosisData) -> np.ndarray:
    """OTHER's residuals (N, 3) under ``fit``'s all-pose model, the base transform refitted per station group."""
    model = fit.model
    theta = fit.all_fit.theta[: model.P]
    res = np.zeros_like(other.points_mm)
    for idx in _groups(other):
        idn = identify(model, other.observations(idx), free=list(BASE_PARAMS), theta0=theta, outliers="off")
        res[idx] = other.points_mm[idx] - model.points(other.q_rad[idx], other.ctx.subset(idx),
                                                       idn.theta[: model.P])
    return res


def _targets_of(data: DiagnosisData, other: DiagnosisData) -> DiagnosisData:
    """OTHER with its rows' targets numbered as the diagnosed model's tool points (OTHER alone may order them
    differently); a target the diagnosed data did not measure is one line."""
    names = other.labels.get("target")
    if names is None:
        return other
    from calib.targets import TargetContext, target_index
    known = list(dict.fromkeys(data.labels.get("target", [])))
    missing = sorted(set(names) - set(known))
    if missing:
        raise RobocalError(f"--confirm {other.source}: target {missing[0]!r} was not measured in {data.source} "
                           f"(its targets: {', '.join(known) or 'none, no target column'})")
    fields = {k: getattr(other.ctx, k) for k in other.ctx.__dataclass_fields__ if k not in ("target", "station")}
    out = other.subset(np.arange(other.n))
    out.ctx = TargetContext(**fields, target=target_index(data.robot, names, other.n))
    return out


def confirm(diag, other: DiagnosisData) -> Confirmation:
    """Each step of ``diag``'s selection (geometric, then + each finding) predicts OTHER."""
    if other.robot.n != diag.data.robot.n:
        raise RobocalError(f"--confirm {other.source}: {other.robot.n} joints, the diagnosed robot has "
                           f"{diag.data.robot.n}")
    other = _targets_of(diag.data, other)
    steps = [("geometric", rms_mm(restationed_residual(diag.geometric, other)))]
    if steps[0][1] > max(10.0, NOT_THE_SAME * diag.baseline_rms_mm):
        raise RobocalError(f"--confirm {other.source}: the geometric model of {diag.data.source} predicts it to "
                           f"{steps[0][1]:.1f} mm RMS after re-stationing (against {diag.baseline_rms_mm:.3f} mm "
                           f"held-out on the data): not the same robot or not the same tool point")
    for f in diag.selection.findings:
        steps.append((f.candidate.label, rms_mm(restationed_residual(f.fit, other))))
    return Confirmation(other.source, other.n, noise_floor_mm(other), steps)
