"""The library of candidate unmodelled effects, instantiated per joint where the data can show them.

Each candidate is one of the model's own effects (:mod:`calib.effects`) with zero (or negligible) initial values and
the list of its parameters to estimate, so scoring, refitting and reporting all go through the one forward model.

A candidate is only offered when the data varies its driver (the effect class's own check,
:func:`calib.effects.drivers.undriven`, shared with ``robocal identify``): backlash needs approach directions, thermal
drift a temperature that varies, compliance a gravity or payload torque (masses in the robot description or a load).  Anything skipped is listed with the reason, so "no finding"
is never confused with "not tested".

Transmission error has an unknown order (cycles per radian of joint angle): it is offered on a grid of orders per
joint, each grid point one candidate; the selection's multiple-test correction counts every grid point.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib.effects.drivers import MIN_RANGE_RAD, undriven
from calib.model import MeasurementModel
from calib.units import DEG

from .candidate import Candidate
from .data import DiagnosisData
from .play import gravity_backlash_candidates

#: the effect names the diagnosis reports (the registry keys of calib.effects.EFFECTS)
EFFECT_NAMES = ("transmission_error", "joint_compliance", "backlash", "backlash_gravity", "cross_coupling",
                "link_compliance", "thermal_drift", "joint_scale", "axis_tilt", "parallel_axes", "instrument_drift",
                "tool_flex", "lateral_compliance")
#: wobbles per turn tried for axis_tilt
AXIS_TILT_ORDERS = (1, 2)
#: step times tried for instrument_drift, as quantiles of the measurement time (besides a ramp)
DRIFT_STEPS = (0.25, 0.5, 0.75)
#: transmission-error orders tried (cycles per radian of joint angle); the thesis found 0.9 and 1.8
TE_ORDERS = tuple(np.round(np.arange(0.5, 4.01, 0.1), 2))


@dataclass
class Library:
    candidates: list[Candidate]
    skipped: list[str] = field(default_factory=list)      # "effect: why it was not tested"


def build_library(data: DiagnosisData, kinds: tuple[str, ...] = EFFECT_NAMES,
                  te_orders: tuple[float, ...] = TE_ORDERS, theta: np.ndarray | None = None) -> Library:
    """Every candidate the data can test, per joint where it applies; the rest listed with the reason.

    Whether the data varies what drives a candidate is the effect's own check (:func:`calib.effects.drivers.undriven`,
    the one ``robocal identify`` refuses an ``--effect`` with): a candidate it rejects is listed under "not tested".
    ``theta``: the geometric fit, where the gravity-loaded backlash grid reads the load torques
    (:mod:`calib.diagnose.play`; the description's nominal values when None)."""
    robot = data.robot
    n = robot.n
    # a joint's own link: a branch link of a tree turns with its joint and a fixed link has no joint of its own, so
    # a joint's running errors are tested once, on the joint (the model carries them to every branch)
    own = [j for j in range(1, n + 1) if robot.variable_of[j - 1] == j - 1]
    rev = [j for j in own if not robot.prismatic[j - 1]]
    rng = np.ptp(data.q_rad, axis=0)
    moving = [j for j in rev if rng[j - 1] >= MIN_RANGE_RAD]
    still = [j for j in rev if rng[j - 1] < MIN_RANGE_RAD]
    out = Library([])
    skip = out.skipped.append
    if still:
        skip(f"joints {', '.join(map(str, still))}: move less than {MIN_RANGE_RAD / DEG:.0f} deg over the poses, "
             f"no joint-angle signature can be tested on them")
    if any(robot.prismatic):
        skip("prismatic joints " + ", ".join(str(j + 1) for j in np.flatnonzero(robot.prismatic)) +
             ": only backlash is tested on them (the other effects are defined for revolute joints)")
    offer = _Offer(data, kinds, out)
    for j in moving:
        for o in te_orders:
            offer(Candidate("transmission_error", j, order=float(o), free=("s1_rad", "c1_rad")))
    offer.all([Candidate("joint_compliance", j, free=("compliance1_rad_per_nm",)) for j in rev])
    if robot.is_tree:
        # a joint bending under the moment of the branches it carries (a torso under both arms); on a serial arm
        # the same moment bends the link beyond it, whose link_compliance candidate has nearly the signature, and
        # the validated diagnosis of arms keeps its library (identify --effect lateral_compliance fits it anywhere)
        pivots = robot.urdf_pivot_mm if robot.urdf_pivot_mm is not None else np.zeros(n)
        offer.all([Candidate("lateral_compliance", j, free=axes, pivot_mm=float(pivots[j - 1]))
                   for j, axes in _bending_axes(data, rev)])
    offer.all([Candidate("backlash", j, free=("width_rad",)) for j in own])
    if "backlash_gravity" in kinds:
        out.candidates += gravity_backlash_candidates(data, theta, out.skipped)
    for j in rev:
        for k in moving:
            if k != j:
                offer(Candidate("cross_coupling", j, source=k, free=("sigma",)))
    offer.all([Candidate("link_compliance", j, free=("compliance_per_nmm2",)) for j in range(1, n + 1)
               if np.hypot(robot.a_mm[j - 1], robot.d_mm[j - 1]) > 10.0 and not robot.prismatic[j - 1]])
    ref = float(np.round(np.mean(data.ctx.temperature_c), 1))
    offer.all([Candidate("thermal_drift", None, reference_c=ref, free=("kappa_per_degc",))])
    _more_candidates(data, moving, offer)
    if data.raw_angles:
        skip("instrument errors: raw theodolite angles are present, but the point-based diagnosis does not refit "
             "them (run robocal identify on the angles)")
    else:
        skip("instrument errors: the data holds intersected points, not raw theodolite angles")
    return out


@dataclass
class _Offer:
    """Adds a candidate of a wanted kind when the data drives it (the effect's own check), else notes why not."""

    data: DiagnosisData
    kinds: tuple[str, ...]
    out: Library

    def why_not(self, c: Candidate) -> str | None:
        return undriven(c.make(), self.data.q_rad, self.data.ctx, self.data.robot)

    def __call__(self, c: Candidate) -> None:
        if c.kind in self.kinds and self.why_not(c) is None:
            self.out.candidates.append(c)

    def all(self, cands: list[Candidate]) -> None:
        """A family of candidates (one per joint): one "not tested" line when they all fail for the same reason."""
        cands = [c for c in cands if c.kind in self.kinds]
        reasons = {id(c): self.why_not(c) for c in cands}
        self.out.candidates += [c for c in cands if reasons[id(c)] is None]
        failed = [c for c in cands if reasons[id(c)] is not None]
        if failed and len(failed) == len(cands) and len({reasons[id(c)] for c in failed}) == 1:
            self.out.skipped.append(f"{failed[0].kind}: {reasons[id(failed[0])]}")
        else:
            self.out.skipped += [f"{c.label}: {reasons[id(c)]}" for c in failed]


#: a bending axis whose moment varies less than this share of the joint's largest is not loaded by these poses
BENDING_SHARE = 1e-3
#: a bending axis this close to the previous joint's axis (mm, and parallel) is that joint's compliance
SAME_AXIS_MM = 10.0


def _bending_axes(data: DiagnosisData, joints: list[int]) -> list[tuple[int, tuple[str, ...]]]:
    """The lateral compliances each joint's bending moment can show: the axes (x, y of the frame its link starts
    from, through its origin) about which the moment it carries varies over the poses, and that are not the axis of
    the joint before it (then the tilt is that joint's own compliance, offered as such).  Gravity alone never loads
    a vertical axis (a pitch joint behind a yaw joint): that compliance is not offered rather than a column of
    zeros."""
    if not joints:
        return []
    robot = data.robot
    model = MeasurementModel(robot)
    fp = model.kin.forward(data.q_rad)
    M = model.loads(fp, data.ctx).joint_moment_nm                                   # (N, n, 3)
    out = []
    for j in joints:
        f = robot.parent_frame[j - 1]
        R = fp.frame_R[:, f]
        spread = np.std(np.einsum("nck,nc->nk", R[:, :, :2], M[:, j - 1]), axis=0)  # about x and y
        names = ("cx_rad_per_nm", "cy_rad_per_nm")
        axes = tuple(name for k, name in enumerate(names) if spread[k] > BENDING_SHARE * spread.max()
                     and not _on_joint_axis(fp, robot, f, R[0, :, k]))
        out.append((j, axes or names))           # no load at all: the driver check says why
    return out


def _on_joint_axis(fp, robot, f: int, axis: np.ndarray) -> bool:
    """Whether the line through frame f's origin along ``axis`` is the axis of the joint whose link ends at frame
    f, within :data:`SAME_AXIS_MM` and 1 degree (first pose: the relation is fixed in that link): a tilt about it
    differs from that joint's own deflection by the tilt times the distance, microns for a milliradian."""
    k = f - 1
    if k < 0 or robot.variable_of[k] < 0 or robot.prismatic[k]:
        return False
    z, o = fp.frame_R[0, robot.parent_frame[k], :, 2], fp.frame_t[0, robot.parent_frame[k]]
    d = fp.frame_t[0, f] - o
    return bool(np.linalg.norm(np.cross(axis, z)) < np.sin(np.radians(1.0))
                and np.linalg.norm(d - (d @ z) * z) < SAME_AXIS_MM)


def _more_candidates(data: DiagnosisData, moving: list[int], offer: _Offer) -> None:
    """Scale errors, wobbling axes, a missing Hayati term, a moving instrument and a bending tool (issue 14)."""
    robot = data.robot
    n = robot.n
    for j in moving:
        offer(Candidate("joint_scale", j, free=("scale",)))
        for k in AXIS_TILT_ORDERS:
            offer(Candidate("axis_tilt", j, order=float(k), free=("c_rad", "s_rad")))
    if "parallel_axes" in offer.kinds:
        pairs = [j for j in range(1, n) if abs(np.sin(robot.alpha_rad[j - 1])) < 1e-3 and not robot.hayati[j - 1]
                 and not robot.prismatic[j - 1]]
        for j in pairs:
            offer(Candidate("parallel_axes", j, free=("beta_rad",)))
        if not pairs:
            offer.out.skipped.append("parallel_axes: no pair of parallel axes without the Hayati term in the robot "
                                     "description")
    t = data.ctx.time_s
    offer.all([Candidate("instrument_drift", None, reference_s=float(np.mean(t)), free=("x_mm", "y_mm", "z_mm"))] +
              [Candidate("instrument_drift", None, step_s=float(np.quantile(t, qv)), free=("x_mm", "y_mm", "z_mm"))
               for qv in DRIFT_STEPS])
    offer(Candidate("tool_flex", None, free=("sag_mm",)))
