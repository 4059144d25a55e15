"""Findings confirmed on independent data: ``robocal diagnose DATA --confirm OTHER.csv [--confirm ...]``.

A finding made on one data set can be an accident of it (its poses, its day).  Confirmation refits nothing but the
instrument-to-base transform on each OTHER session (per ``station`` group: another day or set-up may have moved the
base), with the model of each step of the selection as fitted on DATA held fixed, and compares the RMS on OTHER step
by step.  A finding is confirmed on a session when adding it shrinks the RMS there by at least the share of that
session's excess over its noise floor that the acceptance rule asks on DATA (:data:`calib.diagnose.select.
MATERIAL_SHARE`).

Besides that transfer, each finding's own parameters are refitted on each session alone (the geometric set of the
diagnosis and the findings up to it, started from DATA's values), each with its 1-sigma; they agree with DATA's when
they differ by less than :data:`AGREE_Z` combined sigmas.  An effect confirmed on no session is left out of the
exported model (:func:`exported_effects`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib.errors import RobocalError
from calib.identify import identify
from calib.targets import TargetContext, target_index
from calib.threads import limit

from .data import DiagnosisData
from .export import exported_model
from .gap import CVResult, geometric_free, noise_floor_mm, rms_mm
from .findings import MATERIAL_SHARE

BASE_PARAMS = tuple(f"base.{k}" for k in ("x_mm", "y_mm", "z_mm", "yaw_rad", "pitch_rad", "roll_rad"))
#: poses a station group needs to re-station (6 parameters, 3 observations a pose, and some to spare)
MIN_POSES_PER_STATION = 4
#: OTHER's geometric RMS above this multiple of DATA's (and above 10 mm) means another robot, not another day
NOT_THE_SAME = 50.0
#: a session's refitted parameter agrees with DATA's within this many combined sigmas
AGREE_Z = 2.0


@dataclass
class Confirmation:
    """One OTHER session: the RMS after each step of the selection, and each finding refitted on it alone."""

    source: str
    n: int
    floor_mm: float
    steps: list[tuple[str, float]]        # (label, RMS on OTHER after re-stationing), the geometric model first
    meta: list[dict] = field(default_factory=list)      # per finding: kind, joint, joint_name
    refits: list[dict | None] = field(default_factory=list)   # per finding: parameters refitted on OTHER alone
    final_rms_mm: float | None = None     # the exported model (confirmed findings only), re-stationed

    def findings(self) -> list[dict]:
        excess = self.steps[0][1] - self.floor_mm
        out = []
        for k, ((_, before), (label, after)) in enumerate(zip(self.steps, self.steps[1:])):
            shrink = before - after
            out.append({"label": label, **(self.meta[k] if k < len(self.meta) else {}),
                        "rms_before_mm": before, "rms_after_mm": after, "shrink_mm": shrink,
                        "confirmed": bool(excess > 0 and shrink >= MATERIAL_SHARE * excess),
                        **({"refit": self.refits[k]} if k < len(self.refits) else {})})
        return out

    def as_dict(self) -> dict:
        return {"source": self.source, "poses": self.n, "noise_floor_mm": self.floor_mm,
                "geometric_rms_mm": self.steps[0][1], "final_rms_mm": self.final_rms_mm,
                "findings": self.findings()}


@dataclass
class Confirmations:
    """Every OTHER session, in the order given; what the diagnosis's JSON calls ``confirmation`` (a list)."""

    sessions: list[Confirmation]
    exported: object | None = None        # calib.diagnose.export.Exported: the model --out writes

    def findings(self) -> list[dict]:
        """Per finding over the sessions: confirmed on at least one, and on which."""
        per = [c.findings() for c in self.sessions]
        out = []
        for k in range(len(per[0]) if per else 0):
            on = [c.source for c, f in zip(self.sessions, per) if f[k]["confirmed"]]
            out.append({"confirmed": bool(on), "confirmed_on": on})
        return out

    def as_dict(self) -> list[dict]:
        return [c.as_dict() for c in self.sessions]


def pose_count(data: DiagnosisData) -> int:
    """Poses, not rows: several targets of one pose are one pose."""
    return len(set(data.pose_id)) if data.pose_id else data.n


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


def restationed(model, theta: np.ndarray, other: DiagnosisData) -> tuple[np.ndarray, np.ndarray]:
    """OTHER's residuals (N, 3) under ``model`` at ``theta``, the base transform refitted per station group, and the
    parameter vector of the first group (the start of a refit on OTHER)."""
    res = np.zeros_like(other.points_mm)
    first = None
    for idx in _groups(other):
        idn = identify(model, other.observations(idx), free=list(BASE_PARAMS), theta0=theta, outliers="off")
        th = idn.theta[: model.P]
        first = th if first is None else first
        res[idx] = other.points_mm[idx] - model.points(other.q_rad[idx], other.ctx.subset(idx), th)
    return res, first


def restationed_residual(fit: CVResult, other: DiagnosisData) -> np.ndarray:
    """OTHER's residuals (N, 3) under ``fit``'s all-pose model, the base transform refitted per station group."""
    return restationed(fit.model, fit.all_fit.theta[: fit.model.P], other)[0]


def _targets_of(data: DiagnosisData, other: DiagnosisData) -> DiagnosisData:
    """OTHER with its rows' targets numbered as the diagnosed model's tool points (OTHER alone may order them
    differently); a target the diagnosed data did not measure is one line."""
    names = other.labels.get("target")
    if names is None:
        return other
    known = list(dict.fromkeys(data.labels.get("target", [])))
    missing = sorted(set(names) - set(known))
    if missing:
        raise RobocalError(f"--confirm {other.source}: target {missing[0]!r} was not measured in {data.source} "
                           f"(its targets: {', '.join(known) or 'none, no target column'})")
    fields = {k: getattr(other.ctx, k) for k in other.ctx.__dataclass_fields__ if k not in ("target", "station")}
    out = other.subset(np.arange(other.n))
    out.ctx = TargetContext(**fields, target=target_index(data.robot, names, other.n))
    return out


def check_same_robot(data: DiagnosisData, other: DiagnosisData) -> None:
    """OTHER must be the diagnosed robot's: the same joints, by count and (for a described robot) by name."""
    if other.robot.n != data.robot.n:
        raise RobocalError(f"--confirm {other.source}: {other.robot.n} joints, the diagnosed robot has "
                           f"{data.robot.n}")
    a, b = data.robot.reading_names, other.robot.reading_names
    if tuple(a) != tuple(b):
        raise RobocalError(f"--confirm {other.source}: its joints are {', '.join(b)}, the diagnosed robot's "
                           f"{', '.join(a)}: another robot")


def _effect_of(model, label: str) -> int:
    """Index in ``model.effects`` of the effect a finding is named after (the last one so named)."""
    hits = [i for i, e in enumerate(model.effects) if e.finding_label() == label]
    return hits[-1]


def pose_sigma(model, idn, data: DiagnosisData, names: list[str]) -> np.ndarray:
    """1-sigma of the parameters ``names`` of a fit on ``data``: the larger of the fit's own (Jacobian, inflated by
    the reduced chi-square) and the pose-clustered sandwich estimate ``A (sum_p J_p^T r_p r_p^T J_p) A``,
    ``A = (J^T J)^-1`` over the fit's free parameters, whitened, with the small-sample factor G/(G-1) over the G
    poses.  Why: on real data the misfit is systematic and differs from pose to pose, which the Jacobian's sigma
    (one variance for all) hides; the sandwich is the linearised leave-one-pose-out jackknife, what the
    diagnosis's fold spread measures on the data it diagnosed."""
    free = [n for n in idn.free if n in model.index]
    cols = [model.index[n] for n in free]
    theta = idn.theta[: model.P]
    ev = model.evaluate(data.q_rad, data.ctx, theta, jacobian=True)
    W = data.whitening
    J = np.einsum("nij,njp->nip", W, ev.jacobian[:, :, cols])                    # (N, 3, k)
    r = np.einsum("nij,nj->ni", W, data.points_mm - ev.point_mm)                # (N, 3)
    _, group = np.unique(np.asarray(data.pose_id) if data.pose_id else np.arange(data.n), return_inverse=True)
    G = int(group.max()) + 1
    score = np.zeros((G, len(cols)))
    np.add.at(score, group, np.einsum("nip,ni->np", J, r))
    A = np.linalg.pinv(J.reshape(-1, len(cols)).T @ J.reshape(-1, len(cols)))
    C = A @ (score.T @ score) @ A * G / max(G - 1, 1)
    sand = np.sqrt(np.clip(np.diag(C), 0.0, None))
    own = [free.index(n) for n in names]
    return np.maximum(np.array([idn.sigma[model.index[n]] for n in names]), sand[own])


def refit_on(diag, f, other: DiagnosisData, theta0: np.ndarray) -> dict | None:
    """The finding ``f``'s parameters refitted on OTHER alone (the diagnosis's geometric set and the free parameters
    of the findings up to ``f``, started from DATA's fit re-stationed on OTHER), beside DATA's, with their sigmas
    and whether they agree (:data:`AGREE_Z`).  None when OTHER cannot determine them (the fit fails)."""
    model = f.fit.model
    i = _effect_of(model, f.candidate.label)
    e, s = model.effects[i], model.effect_slices[i]
    own = [n for n in model.names[s] if n.split(".")[-1] in f.candidate.free]
    effects_free = [n for n in f.fit.all_fit.free if n in model.index and model.index[n] >= model.n_geometric]
    free = list(dict.fromkeys(geometric_free(model, diag.level) + effects_free + own))
    try:
        idn = identify(model, other.observations(), free=free, theta0=theta0, outliers="off", start=False)
    except RobocalError:
        return None
    train = f.fit.all_fit
    st, so = pose_sigma(model, train, diag.data, own), pose_sigma(model, idn, other, own)
    values_t = {n.split(".")[-1]: float(train.theta[model.index[n]]) for n in own}
    sig_t = {n.split(".")[-1]: float(st[k]) for k, n in enumerate(own)}
    values_o = {n.split(".")[-1]: float(idn.theta[model.index[n]]) for n in own}
    sig_o = {n.split(".")[-1]: float(so[k]) for k, n in enumerate(own)}
    free_short = [n.split(".")[-1] for n in own]
    z = {k: abs(values_o[k] - values_t[k]) / max(np.hypot(sig_o[k], sig_t[k]), 1e-300) for k in free_short}
    return {"training": e.edge_parameters(values_t, sig_t, free_short),
            "session": e.edge_parameters(values_o, sig_o, free_short),
            "z": z, "agree": bool(all(v <= AGREE_Z for v in z.values())), "fit_rms_mm": idn.residual_rms}


def confirm(diag, other: DiagnosisData, keep: list[int] | None = None) -> Confirmation:
    """Each step of ``diag``'s selection (geometric, then + each finding) predicts OTHER; each finding refitted on
    OTHER alone.  ``keep``: the findings of the exported model, whose RMS on OTHER is ``final_rms_mm`` (None: skip)."""
    check_same_robot(diag.data, other)
    other = _targets_of(diag.data, other)
    steps = [("geometric", rms_mm(restationed_residual(diag.geometric, other)))]
    if steps[0][1] > max(10.0, NOT_THE_SAME * diag.baseline_rms_mm):
        raise RobocalError(f"--confirm {other.source}: the geometric model of {diag.data.source} predicts it to "
                           f"{steps[0][1]:.1f} mm RMS after re-stationing (against {diag.baseline_rms_mm:.3f} mm "
                           f"held-out on the data): not the same robot or not the same tool point")
    meta, refits = [], []
    for f in diag.selection.findings:
        res, th = restationed(f.fit.model, f.fit.all_fit.theta[: f.fit.model.P], other)
        steps.append((f.candidate.label, rms_mm(res)))
        meta.append({"kind": f.candidate.kind, "joint": f.candidate.joint,
                     "joint_name": diag.data.joint_name(f.candidate.joint)})
        refits.append(refit_on(diag, f, other, th))
    out = Confirmation(other.source, pose_count(other), noise_floor_mm(other), steps, meta, refits)
    return out


def confirm_all(diag, others: list[DiagnosisData]) -> Confirmations:
    """:func:`confirm` on every OTHER session, in order; then the exported model (the findings confirmed on at
    least one session, :func:`calib.diagnose.export.exported_model`) and its RMS on each session."""
    with limit(1):              # small matrices: BLAS threads cost more than they give (as in the diagnosis)
        return _confirm_all(diag, others)


def _confirm_all(diag, others: list[DiagnosisData]) -> Confirmations:
    out = Confirmations([confirm(diag, o) for o in others])
    out.exported = exported_model(diag, [f["confirmed"] for f in out.findings()])
    m = out.exported.model
    for c, o in zip(out.sessions, others):
        c.final_rms_mm = rms_mm(restationed(m, out.exported.ident.theta[: m.P], _targets_of(diag.data, o))[0])
    return out
