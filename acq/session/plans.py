"""A session's plan for any robot, from its profile (:mod:`calib.profile`) and the set-up: every procedure that
applies, with the parameters of a preset -- :data:`CELL` for a real cell (more positions), :data:`DEMO` for an
emulated session (fewer, every procedure still present, ``robocal demo`` stays quick).

Which procedures: the transmission error on the profile's joints (``--te-joints`` to choose), the joint compliance
on the joints the set-up loads, the link compliance when the set-up has a link, the coupling on the description's
coupled pairs and the encoder resolution on the last joint -- the last two only where the encoder tap reads the
robot.  Each transmission-error run is narrowed to what the cell can see (:func:`runs_in_sight`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.errors import RobocalError
from calib.jsonfile import vouch
from calib.profile import RobotProfile, profile_of
from calib.robot import Robot
from calib.loading import load_robot

from .iso_cube import iso_plan
from .plan_doc import PLAN_SCHEMA
from .preflight import Preflight
from .procedures import transmission
from .setup_types import BenchSetup, setup_of

#: a real cell's parameters (per procedure; ``None``: the procedure is not in the default plan)
CELL = {"ruler": {"repeats": 2}, "sweeps": {"points": 8, "span_deg": 90.0},
        "transmission": {"points": 25, "repeats": 2}, "compliance": {}, "coupling": {"angle_deg": 10.0},
        "encoder_resolution": None, "iso9283": {"cycles": 30}}
#: ISO 9283 cycles per pose in the demo: fewer than the standard's 30 (the demo stays quick), said in its output
DEMO_ISO_CYCLES = 5
#: the demo's: fewer positions and repeats than a real session, but every procedure
DEMO = {"ruler": {"repeats": 2}, "sweeps": {"points": 5, "span_deg": 60.0},
        "transmission": {"points": 25, "repeats": 2}, "compliance": {"repeats": 3},
        "coupling": {"angle_deg": 10.0, "repeats": 4},
        "encoder_resolution": {"points": 6, "span_deg": 150.0, "repeats": 1},
        "iso9283": {"cycles": DEMO_ISO_CYCLES}}
#: a run narrowed to the cell's sight keeps this far from the first offset that failed (deg)
SIGHT_MARGIN_DEG = 5.0


def transmission_plan(joints=None, points: int = 25, repeats: int = 2, profile: RobotProfile | None = None) -> dict:
    """The plan's ``transmission`` entry for ``joints`` (default: the profile's runs), each over the profile's range
    for it (:attr:`calib.profile.RobotProfile.te_range_deg`; default profile: the thesis's Puma); what
    ``--te-joints`` of ``robocal session`` and ``robocal demo`` maps to."""
    profile = profile or profile_of(load_robot(None))
    js = [int(j) for j in (joints or profile.te_joints)]
    planned = sorted(profile.te_range_deg)
    if any(j not in planned for j in js):
        raise RobocalError(f"--te-joints {','.join(map(str, js))}: must list distinct joints among "
                           f"{','.join(map(str, planned))} (each has a planned range for {profile.name})")
    return {"joints": js, "points": points, "repeats": repeats,
            "range_deg": {str(j): list(profile.te_range_deg[j]) for j in js}}


def runs_in_sight(plan: dict, setup: BenchSetup, preflight: Preflight, rounds: int = 4) -> None:
    """Each transmission-error run narrowed to the widest window about the reference pose whose every step passes
    the pre-flight (a joint turned far enough puts the arm between a station and a target on some robots): the
    profile's range is what the joint's limits allow, the window what the cell can see."""
    te = plan["transmission"]
    for _ in range(rounds):
        # the runs as a plan of their own, which this module built from checked joints: vouched for, not checked
        runs = vouch({"procedures": ["transmission"], "seed": plan.get("seed", 0), "transmission": te}, PLAN_SCHEMA)
        failed = {f.key for f in preflight.check(list(transmission(runs, setup)))}
        if not failed:
            return
        for j in te["joints"]:
            lo, hi = te["range_deg"][str(j)]
            offsets = np.linspace(lo, hi, te["points"])
            bad = [a for i, a in enumerate(offsets) if f"te/j{j}/{i:02d}" in failed]
            if bad:
                below, above = [a for a in bad if a < 0], [a for a in bad if a >= 0]
                te["range_deg"][str(j)] = [float(max(below) + SIGHT_MARGIN_DEG) if below else lo,
                                           float(min(above) - SIGHT_MARGIN_DEG) if above else hi]


def session_plan(robot: Robot, setup: BenchSetup | dict, preset: dict, te_joints=None, poses_deg=None,
                 seed: int = 0, model_path: str | None = None) -> dict:
    """The plan (see the module docstring) for ``robot`` on the bench ``setup`` (a session set-up, its old keys
    mapped: :func:`acq.session.setup.session_setup`) with the ``preset``'s parameters and the pose set
    ``poses_deg`` when given."""
    setup = setup_of(setup)
    profile = profile_of(robot)
    plan: dict = {"procedures": ["levelling", "instrument_check", "ruler", "sweeps"], "ruler": dict(preset["ruler"]),
                  "sweeps": {**preset["sweeps"], "joints": list(profile.sweep_joints)}, "seed": seed}
    if poses_deg is not None:
        plan["procedures"].append("poses")
        plan["poses"] = {"q_deg": [[round(float(v), 4) for v in row] for row in poses_deg]}
    if te_joints or profile.te_joints:
        plan["procedures"].append("transmission")
        plan["transmission"] = transmission_plan(te_joints, profile=profile, **preset["transmission"])
        runs_in_sight(plan, setup, Preflight(robot, setup))
    if setup.compliance:
        plan["procedures"].append("compliance")
        plan["compliance"] = {**preset["compliance"], "joints": sorted(setup.compliance)}
    if setup.link is not None:
        plan["procedures"].append("link_compliance")
    if profile.tapped and profile.coupled_pairs:
        plan["procedures"].append("coupling")
        plan["coupling"] = {**preset["coupling"], "pairs": [list(p) for p in profile.coupled_pairs]}
    if profile.tapped and preset["encoder_resolution"] is not None:
        plan["procedures"].append("encoder_resolution")
        plan["encoder_resolution"] = {**preset["encoder_resolution"], "joints": list(profile.sweep_joints[-1:])}
    add_iso9283(plan, robot, setup, preset, seed, model_path)
    return plan


def add_iso9283(plan: dict, robot: Robot, setup: BenchSetup, preset: dict, seed: int = 0,
                model_path: str | None = None) -> None:
    """ISO 9283 at the end of the plan (:mod:`acq.session.iso_cube`): both runs when the plan has a pose set (the
    compensated commands come from the model it identifies) or a calibrated model file (``model_path``), the
    uncompensated one alone otherwise.  A robot with
    no cube in sight of the stations gets none, unless the set-up asks for it (then the reason is the error)."""
    if preset.get("iso9283") is None and setup.iso9283 is None:
        return
    runs = ("off", "on") if "poses" in plan["procedures"] or model_path else ("off",)
    try:
        plan["iso9283"] = iso_plan(robot, setup, (preset.get("iso9283") or {}).get("cycles", 30), runs, seed)
        if model_path:
            plan["iso9283"]["model"] = str(Path(model_path).resolve())
    except RobocalError:
        if setup.iso9283 is not None:
            raise
        return
    plan["procedures"].append("iso9283")
