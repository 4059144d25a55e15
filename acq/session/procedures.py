"""Every Chapter 4 procedure (and the Chapter 6 pose set) as a generator of :class:`~acq.session.steps.Step`.

Read a procedure top to bottom to know what the operator will be asked, in order.  Procedures take the session
``plan`` (their parameters: :class:`~acq.session.plan_doc.SessionPlan`, or its JSON form, checked on entry) and
``setup`` (the geometry of the bench: :class:`~acq.session.setup_types.BenchSetup`, typed once by
:func:`all_steps`) and never touch a device: the runner does the
I/O, checks and storage.  Step keys are stable (``sweep/j2/03``), so a resumed session skips what is committed.

Units: poses in degrees (what the operator types into the teach pendant), lengths in mm, loads as masses in kg (old set-ups: forces in N).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np

from calib.errors import RobocalError
from calib.units import G0_M_S2

from . import checks as ck
from .plan_doc import SessionPlan, plan_of
from .setup import point_p, reference_pose_deg, setup_profile, station_names
from .setup_types import BenchSetup, ComplianceLoad, LinkLoad, mark_index, setup_of
from .steps import InputSpec, Step, TargetSpec


def _fmt(q) -> str:
    return "[" + ", ".join(f"{v:.1f}" for v in q) + "] deg"


def _both(setup: BenchSetup) -> str:
    """"theodolite A, then with B" with the set-up's station names."""
    a, b = station_names(setup)
    return f"theodolite {a}, then with {b}"


def _pose(j: int, angle_deg: float, base) -> tuple[float, ...]:
    q = list(base)
    q[j - 1] += angle_deg
    return tuple(q)


def tool_target(setup: BenchSetup) -> TargetSpec:
    if setup.tool_target_mm is None:
        raise RobocalError("set-up: tool_target_mm: missing (the steps sighting the tool target need it)")
    return TargetSpec("P", tool_mm=setup.tool_target_mm)


def sweep_target(setup: BenchSetup, j: int) -> TargetSpec:
    """Target P_j of joint j's sweep: the set-up's designed one (``sweep_targets``), else the tool target."""
    tg = (setup.sweep_targets or {}).get(j)
    if tg is None:
        return tool_target(setup)
    return TargetSpec("P", tool_mm=tg.point_mm, link=tg.link)


def extended_targets(setup: BenchSetup) -> tuple[TargetSpec, TargetSpec]:
    et = setup.extended_tool
    if et is None:
        raise RobocalError("set-up: extended_tool: missing (the runs on A1 and A2 need it)")
    return TargetSpec("A1", tool_mm=et.A1_mm), TargetSpec("A2", tool_mm=et.A2_mm)


# -- 4.2 levelling and the instrument check ---------------------------------------------------------------------------
def levelling(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """Each theodolite levelled before anything is sighted: the thesis's analysis assumes parallel vertical axes
    (section 4.2, assumption 1).  The operator enters the residual tilt its level shows (electronic level: the two
    inclination readings; plate level only: the bubble's offset converted with its sensitivity)."""
    for name in station_names(setup):
        yield Step(
            key=f"level/{name}", procedure="levelling", title=f"Level theodolite {name}",
            instruction=(f"Level theodolite {name}: plate level parallel to two foot screws, centre it, turn 90 deg, "
                         f"centre it with the third; repeat until it stays centred all round. Then enter the residual "
                         f"tilt the instrument shows across and along the telescope (arc seconds)."),
            targets=(), faces=(), encoders=False,
            inputs=(InputSpec("tilt_cross_arcsec", "arcsec", f"Theodolite {name}: tilt across the telescope", 0.0),
                    InputSpec("tilt_length_arcsec", "arcsec", f"Theodolite {name}: tilt along the telescope", 0.0)),
            setup={"station": name}, meta={"station": name})


def instrument_check(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """Both faces of both instruments on a far target: their collimation and index errors.  Two-face means cancel
    them, but an instrument far out of adjustment (or a face change that did not happen) shows here first."""
    p = plan_of(plan).instrument_check
    far = setup.far_target_mm
    yield Step(
        key="instrument/far", procedure="instrument_check", title="Instrument check on the far target",
        instruction=("Sight the far target F (a sharp mark on the wall, a few metres away) with each theodolite, face "
                     "I then face II, twice. The check compares the faces: collimation and index error."),
        targets=(TargetSpec("F", point_mm=None if far is None else tuple(float(v) for v in far)),),
        faces=(1, 2), repeats=p.repeats, encoders=False, meta={})


# -- 4.2 ruler -----------------------------------------------------------------------------------------------------
def ruler(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """Theodolite pre-calibration: marks C, D, E of a ruler, levelled in the stations' plane, both faces.

    A placement sights every mark, or those it lists (``marks``: names) -- the series that varies R as the thesis
    does (Fig 5.4: R from 1792 to 1860 mm) marks E at several distances and sights one of them per placement, with C
    and the last mark on every placement (the fit starts from the ruler's two ends)."""
    r = setup.ruler
    marks = r.marks_mm
    sta, stb = station_names(setup)
    p = plan_of(plan).ruler
    for k, pl in enumerate(r.placements):
        c = np.asarray(pl.C_mm, float) if pl.C_mm is not None else None
        u = np.asarray(pl.dir, float)
        for name in r.sighted(pl):
            m = mark_index(name)
            point = None if c is None else tuple(float(v) for v in c + marks[m] * u / np.linalg.norm(u))
            yield Step(
                key=f"ruler/p{k}/{name}", procedure="ruler", title=f"Ruler placement {k + 1}: mark {name}",
                instruction=(f"Ruler placement {k + 1} ({pl.where or 'as set up'}), levelled in the plane of "
                             f"the theodolites. Sight mark {name} ({marks[m]:.1f} mm from C) with theodolite {sta}, "
                             f"then with {stb}, face I then face II."),
                targets=(TargetSpec(name, point_mm=point),), repeats=p.repeats, encoders=False,
                meta={"placement": k, "mark": m})


# -- 4.3 joint sweeps ------------------------------------------------------------------------------------------------
def sweeps(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """Joint orientations and centres: each joint swept alone from READY (the set-up's reference pose), target P
    sighted at each position; by default every revolute joint of the robot."""
    p = plan_of(plan).sweeps
    n, span = p.points, p.span_deg
    ready = reference_pose_deg(setup)
    joints = p.joints or setup_profile(setup).sweep_joints
    for j in joints:
        for i, a in enumerate(np.linspace(-span / 2, span / 2, n)):
            q = _pose(j, float(a), ready)
            yield Step(
                key=f"sweep/j{j}/{i:02d}", procedure="sweep", title=f"Joint {j} sweep, position {i + 1}/{n}",
                instruction=(f"Other joints at READY. Rotate joint {j} to about {q[j - 1]:+.1f} deg (always in "
                             f"the positive direction), sight target P with {_both(setup)}."),
                pose_deg=q, targets=(sweep_target(setup, j),), repeats=p.repeats,
                meta={"joint": j, "index": i, "swept_joint": j})
    pp = point_p(setup)
    # P serves d3 with the wrist centre (the last two joints' axes): sighted only when the set-up has a P, the plan
    # sweeps those joints, and the robot's profile has the thesis's scheme (eq 4.3.15 is its Puma's)
    if pp is not None and p.point_p and _wrist_swept(setup, joints):
        link, tool, lp = pp
        yield Step(
            key="sweep/p", procedure="sweep", title="Point P on the tool's axis (d3, eq 4.3.15)",
            instruction=(f"All joints at READY {_fmt(ready)}. Sight point P, the mark on the tool's axis "
                         f"{lp:g} mm beyond the flange (L_p), with {_both(setup)}."),
            pose_deg=tuple(ready), targets=(TargetSpec("P", tool_mm=tool, link=link),),
            repeats=p.repeats, meta={"point": "P", "L_p_mm": lp})


def _wrist_swept(setup: BenchSetup, joints) -> bool:
    """Point P belongs to the thesis's scheme: its robot profile has it, and the plan sweeps the wrist's last two
    joints (their axes give the wrist centre P is measured from)."""
    profile = setup_profile(setup)
    return profile.point_p and {profile.n - 1, profile.n} <= set(joints)


# -- Chapter 6 pose set ----------------------------------------------------------------------------------------------
def poses(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """The identification pose set (from ``robocal plan poses`` or chosen at session creation)."""
    p = plan_of(plan).poses
    qs = p.q_deg
    for i, q in enumerate(qs):
        yield Step(
            key=f"poses/{i:03d}", procedure="poses", title=f"Pose {i + 1}/{len(qs)}",
            instruction=f"Move the robot to {_fmt(q)}, sight target P with {_both(setup)}.",
            pose_deg=tuple(q), targets=(tool_target(setup),), repeats=p.repeats, meta={"index": i})


# -- 4.4 transmission error ------------------------------------------------------------------------------------------
def transmission(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """Joint angle from the extended tool's targets A1, A2 against the encoder, over a joint's range."""
    p = plan_of(plan).transmission
    a1, a2 = extended_targets(setup)
    ready = reference_pose_deg(setup)
    profile = None if p.joints and all(str(j) in p.range_deg for j in p.joints) else setup_profile(setup)
    for j in p.joints or profile.te_joints:
        lo, hi = p.range_deg.get(str(j)) or profile.te_range_deg[j]
        n = p.points
        for i, a in enumerate(np.linspace(lo, hi, n)):
            q = _pose(j, float(a), ready)
            yield Step(
                key=f"te/j{j}/{i:02d}", procedure="transmission", title=f"Joint {j} transmission error {i + 1}/{n}",
                instruction=(f"Extended tool fitted. Rotate joint {j} to {q[j - 1]:+.1f} deg (positive direction "
                             f"only, no load), sight A1 then A2 with {_both(setup)}."),
                pose_deg=q, targets=(a1, a2), repeats=p.repeats, meta={"joint": j, "index": i})


def _hung(link: int | None, point_mm, loads_n, masses_kg, load_n: float) -> dict:
    """The step's hung mass in the step vocabulary (a mass at a point on a link), when the set-up gives the point
    (:func:`acq.session.setup.session_setup` maps old set-ups); ``tested_joint``: the joint it must turn."""
    if point_mm is None or not loads_n:
        return {}
    kg = dict(zip(loads_n, masses_kg if masses_kg is not None else [v / G0_M_S2 for v in loads_n]))
    return {"loads": [{"link": int(link), "point_mm": list(point_mm), "mass_kg": kg[load_n]}],
            "tested_joint": int(link)}


# -- 4.5 joint compliance --------------------------------------------------------------------------------------------
def compliance(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """Masses hung at a point on link j (a lever), increasing then decreasing; A1, A2 sighted at each load.

    In the step vocabulary (contract C3) each step hangs ``step.setup["loads"]`` (one mass at the set-up's point) with
    ``load_direction`` ``{"j": +1 / -1}``, and the operator enters the mass actually hung (``load_kg``); a set-up
    without points (not mapped by :func:`acq.session.setup.session_setup`) keeps the old lever prompts in N."""
    p = plan_of(plan).compliance
    a1, a2 = extended_targets(setup)
    sta, stb = station_names(setup)
    for j in p.joints or sorted(setup.compliance):
        cfg = setup.compliance.get(j)
        if cfg is None:
            raise RobocalError(f"set-up: compliance: the plan loads joint {j}, the set-up has no entry \"{j}\"")
        loads = list(cfg.loads_n)
        series = [("load", v, +1) for v in loads] + [("unload", v, -1) for v in reversed(loads[:-1])]
        q = tuple(cfg.pose_deg or reference_pose_deg(setup))
        for i, (phase, load, direction) in enumerate(series):
            hung = _hung(cfg.link, cfg.point_mm, cfg.loads_n, cfg.masses_kg, load)
            what = f"{hung['loads'][0]['mass_kg']:.3g} kg ({load:g} N)" if hung else f"{load:g} N"
            yield Step(
                key=f"compliance/j{j}/{i:02d}", procedure="compliance",
                title=f"Joint {j} {'loading' if direction > 0 else 'unloading'}: {what}",
                instruction=(f"Brakes released, robot holding {_fmt(q)}. "
                             f"{'Hang' if direction > 0 else 'Remove weights to leave'} {what} on the lever at "
                             f"{cfg.lever_mm:g} mm from joint {j}'s axis, wait for the arm to settle, enter the "
                             f"load, then sight A1 and A2 with theodolite {sta}, then with {stb}."),
                pose_deg=q, targets=(a1, a2), repeats=p.repeats,
                inputs=_load_inputs(j, cfg, load, hung),
                setup={"joint": j, "load_n": load, "lever_mm": cfg.lever_mm,
                       "theta_i_deg": cfg.theta_i_deg,
                       "load_direction": {str(j): direction} if hung else direction, **hung},
                meta={"joint": j, "index": i, "phase": phase})


def _load_inputs(j: int, cfg: ComplianceLoad, load_n: float, hung: dict) -> tuple[InputSpec, ...]:
    """What the operator enters at a compliance step: the load (kg when the step hangs a mass), the lever as
    measured and its angle from level (recorded with the step)."""
    load = (_load_spec("load_kg", "kg", f"Mass now on the lever of joint {j}", hung["loads"][0]["mass_kg"]) if hung
            else _load_spec("load_n", "N", f"Load now on the lever of joint {j}", load_n))
    lever = float(cfg.lever_mm)
    return (load, InputSpec("lever_mm", "mm", "Lever arm from the joint's axis", lever,
                            tolerance=max(LEVER_REL_TOL * lever, LEVER_MIN_TOL_MM)),
            InputSpec("theta_i_deg", "deg", "Lever angle from the horizontal", cfg.theta_i_deg,
                      tolerance=LEVER_ANGLE_TOL_DEG))


#: how far an entered load may be from the plan's before the "as planned" check fails: a different mass (the 5 kg
#: set where 1.02 kg was planned), not the scale's error -- 10 % of the planned load, at least 0.05 kg (0.5 N)
LOAD_REL_TOL, LOAD_MIN_TOL = 0.10, {"kg": 0.05, "N": 0.5}
#: a lever measured more than 5 % (at least 5 mm) off the plan's is another hole; its angle more than 5 deg off level
LEVER_REL_TOL, LEVER_MIN_TOL_MM, LEVER_ANGLE_TOL_DEG = 0.05, 5.0, 5.0


def _load_spec(name: str, unit: str, prompt: str, planned: float) -> InputSpec:
    """A load input with the plan's value as its hint and the tolerance that tells a different mass."""
    planned = float(planned)
    return InputSpec(name, unit, prompt, planned, tolerance=max(LOAD_REL_TOL * abs(planned), LOAD_MIN_TOL[unit]))


# -- 4.6 link compliance ---------------------------------------------------------------------------------------------
def link_compliance(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """Dial gauges along a link, loads at its end; the operator enters the gauge readings."""
    cfg: LinkLoad | None = setup.link
    if cfg is None:
        raise RobocalError("set-up: link: missing (the link-compliance procedure needs it)")
    j = cfg.joint
    xs = cfg.gauges_x_mm
    for i, load in enumerate(cfg.loads_n):
        hung = _hung(cfg.link if cfg.link is not None else j, cfg.load_point_mm, cfg.loads_n, cfg.masses_kg, load)
        yield Step(
            key=f"link/j{j}/{i:02d}", procedure="link_compliance", title=f"Link {j}: load {load:g} N",
            instruction=(f"Dial gauges at {', '.join(f'{x:g}' for x in xs)} mm from joint {j}'s centre, zeroed "
                         f"without load. Hang {load:g} N at {cfg.load_x_mm:g} mm, wait 30 s, read every gauge."),
            pose_deg=tuple(cfg.pose_deg or reference_pose_deg(setup)), targets=(), faces=(),
            inputs=(_link_load_input(hung, load),
                    *[InputSpec(f"gauge{g + 1}_mm", "mm", f"Dial gauge {g + 1} at {x:g} mm")
                      for g, x in enumerate(xs)]),
            setup={"joint": j, "load_n": load, "load_x_mm": cfg.load_x_mm, "gauges_x_mm": list(xs), **hung,
                   **({"gauges": [g.to_doc() for g in cfg.gauges]} if cfg.gauges is not None else {})},
            meta={"joint": j, "index": i})


def _link_load_input(hung: dict, load_n: float) -> InputSpec:
    """The link step's load as the operator enters it: the mass hung (kg, contract C3) when the step hangs one, the
    old force prompt (N) for a set-up without load points."""
    if hung:
        return _load_spec("load_kg", "kg", "Mass hung", hung["loads"][0]["mass_kg"])
    return _load_spec("load_n", "N", "Load hung", load_n)


# -- 4.7 wrist coupling ----------------------------------------------------------------------------------------------
def coupling(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """Joint k alone through theta, then j and k together: the encoder of k shows sigma_jk theta_j more."""
    p = plan_of(plan).coupling
    th = p.angle_deg
    repeats = p.repeats
    for j, k in p.pairs or setup_profile(setup).coupled_pairs:
        start = reference_pose_deg(setup)
        alone = _pose(k, th, start)
        both = _pose(j, th, alone)
        for r in range(repeats):
            # repeats: the scatter between them (servo repeatability) is pooled into sigma_jk's error by reprocess;
            # the first repeat keeps the old key, so sessions recorded without repeats resume unchanged
            tag, of = ("" if r == 0 else f"/r{r}"), ("" if repeats == 1 else f" (repeat {r + 1}/{repeats})")
            for name, q, text in (
                    ("start", start, f"Move to READY {_fmt(start)} and hold; the encoder stream is recorded."),
                    ("alone", alone, f"Rotate joint {k} alone by {th:+g} deg, hold."),
                    ("return", start, "Return to READY, hold."),
                    ("with", both, f"Rotate joints {j} and {k} together by {th:+g} deg each, hold.")):
                yield Step(
                    key=f"coupling/j{j}k{k}/{name}{tag}", procedure="coupling",
                    title=f"Coupling {j}->{k}: {name}{of}",
                    instruction=text + " No sightings.", pose_deg=q, targets=(), faces=(),
                    meta={"j": j, "k": k, "phase": name, "angle_deg": th, "repeat": r})


# -- 5.4.2 encoder resolution -----------------------------------------------------------------------------------------
def encoder_resolution(plan: SessionPlan, setup: BenchSetup) -> Iterator[Step]:
    """Joint j stepped in one direction while A1, A2 are sighted and the encoder tapped (thesis Fig 5.14): the slope
    of the measured angle on the counts is the resolution achieved.  Why the default span is wide (150 deg):
    reprocess fits the joint's axis from A2 over the run itself, and a 30 deg arc leaves it tilted enough to bias the
    slope by 0.5 % (measured on the demo's twin); it stays below 180 deg because the angles are taken from the first
    step.  The fitted axis's own error is in the slope's error (reprocess ``_resolution``): with the extended tool's
    A1->A2 line as much along the axis as across it, it is most of that error."""
    p = plan_of(plan).encoder_resolution
    a1, a2 = extended_targets(setup)
    n, span = p.points, p.span_deg
    for j in p.joints or setup_profile(setup).sweep_joints[-1:]:
        for i, a in enumerate(np.linspace(0.0, span, n)):
            q = _pose(j, float(a), reference_pose_deg(setup))
            yield Step(
                key=f"resolution/j{j}/{i:02d}", procedure="encoder_resolution",
                title=f"Joint {j} encoder resolution {i + 1}/{n}",
                instruction=(f"Extended tool fitted. Step joint {j} to {q[j - 1]:+.2f} deg (positive direction only, "
                             f"no load), hold; the encoder stream is recorded; sight A1 then A2 with {_both(setup)}."),
                pose_deg=q, targets=(a1, a2), repeats=p.repeats, meta={"joint": j, "index": i})


# -- ISO 9283 pose accuracy and repeatability ------------------------------------------------------------------------
def iso9283(plan: dict, setup: dict) -> Iterator[Step]:
    """The five poses of the ISO 9283 cube (:mod:`acq.session.iso_cube`), ``cycles`` times each, every measurement
    after the same approach move (every joint arriving in the positive direction), target P sighted like a pose of
    the pose set.  Run ``off`` commands the nominal joint command; run ``on`` the calibrated model's command for the
    same point, which the runner's ``command`` hook supplies when the step is reached
    (:class:`offline.iso_commands.CompensatedCommands`): the step carries the nominal one until then."""
    p = plan_of(plan).iso9283
    target = tool_target(setup)
    for run in p.runs:
        for c in range(p.cycles):
            for pose in p.poses:
                yield iso_step(run, c, p.cycles, pose, p.approach_deg, target, setup)


def iso_step(run: str, cycle: int, cycles: int, pose, approach_deg: float, target: TargetSpec, setup: dict) -> Step:
    """One ISO 9283 measurement: pose ``pose`` (:class:`~acq.session.plan_doc.IsoPose`) in cycle ``cycle``."""
    q = tuple(pose.q_deg)
    approach = tuple(v - approach_deg for v in q)
    on = run == "on"
    command = "the calibrated model's command for the same point" if on else _fmt(q)
    return Step(
        key=f"iso9283/{run}/c{cycle:02d}/{pose.pose}", procedure="iso9283",
        title=f"ISO 9283, compensation {run}: pose {pose.pose}, cycle {cycle + 1}/{cycles}",
        instruction=(f"Move the robot to the approach pose {_fmt(approach)}, then to {command} (every joint arriving "
                     f"in the positive direction), sight target P with {_both(setup)}."),
        pose_deg=q, targets=(target,), encoders=False,
        setup={"approach_deg": list(approach), **({"command": "compensated"} if on else {})},
        meta={"run": run, "pose": pose.pose, "cycle": cycle, "point_mm": list(pose.point_mm), "nominal_deg": list(q)})


@dataclass(frozen=True)
class ProcedureInfo:
    """What the rest of the session needs to know about a procedure, found by name instead of name branches:
    its step generator, extra acceptance checks ``(step, readings, values, limits) -> list[Check]`` (readings as
    stored, the operator's values by input name) and whether its accepted steps refit the stations (the ruler)."""

    steps: Callable[[SessionPlan, BenchSetup], Iterator[Step]]
    checks: tuple = ()
    refits_stations: bool = False


REGISTRY: dict[str, ProcedureInfo] = {}
#: plan name -> step generator (kept for callers that list the procedures)
PROCEDURES: dict[str, Callable[[dict, dict], Iterator[Step]]] = {}
#: step.procedure -> plan name (a procedure's steps may carry a shorter name: sweeps -> sweep)
_STEP_NAMES: dict[str, str] = {}


def register_procedure(name: str, steps: Callable, step_name: str | None = None, checks: tuple = (),
                       refits_stations: bool = False) -> None:
    REGISTRY[name] = ProcedureInfo(steps, tuple(checks), refits_stations)
    PROCEDURES[name] = steps
    _STEP_NAMES[step_name or name] = name


_DEFAULT_INFO = ProcedureInfo(lambda plan, setup: iter(()))


def procedure_info(step_procedure: str) -> ProcedureInfo:
    """The registry entry of a step's procedure (an unknown one -- an imported step -- has no extras)."""
    return REGISTRY.get(_STEP_NAMES.get(step_procedure, step_procedure), _DEFAULT_INFO)


register_procedure("levelling", levelling, checks=(ck.levelled,))
register_procedure("instrument_check", instrument_check, checks=(ck.instrument_errors,))
register_procedure("ruler", ruler, refits_stations=True)
register_procedure("sweeps", sweeps, step_name="sweep")
register_procedure("poses", poses)
register_procedure("transmission", transmission)
register_procedure("compliance", compliance)
register_procedure("link_compliance", link_compliance)
register_procedure("coupling", coupling)
register_procedure("encoder_resolution", encoder_resolution)
register_procedure("iso9283", iso9283)


def all_steps(plan: dict | SessionPlan, setup: dict | BenchSetup) -> list[Step]:
    """Every step of the session's plan (checked here, once: :func:`acq.session.plan_doc.plan_of`, and the set-up:
    :func:`acq.session.setup_types.setup_of`), in order; keys are checked for uniqueness (resume depends on them)."""
    plan = plan_of(plan)
    setup = setup_of(setup)
    out: list[Step] = []
    for name in plan.procedures:
        try:
            proc = PROCEDURES[name]
        except KeyError:
            raise RobocalError(f"session plan: unknown procedure {name!r} (known: {', '.join(PROCEDURES)})")
        out.extend(proc(plan, setup))
    keys = [s.key for s in out]
    assert len(keys) == len(set(keys)), "duplicate step keys"
    return out
