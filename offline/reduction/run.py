"""The reduction as one loop over the stages (:mod:`offline.reduction.stages`), in dependency order, each from the
*stored raw readings* of its procedures only.  A stage that fails says why in ``problems`` and the others still run;
a stage that does not apply to the robot (its profile) is skipped, and a procedure recorded for it is said to be
left unreduced.

Output: the results document -- ``session``, ``provenance``, ``estimates`` (name, value, error 1 sigma, unit,
``truth`` None: an emulated session's truths are the simulation side's, :mod:`sim.emulate.truth`), ``bounds``,
``accuracy``, ``problems`` (for the operator) and ``problem_details`` (their technical causes), ``robot`` (the
identified model document), ``figures`` (for the report), ``profile`` (what the reduction took the robot to be) and
``trace`` (per stage, what an independent check of its estimates needs: not written to files).
"""
from __future__ import annotations

import time

from calib.errors import RobocalError
from calib.kinematics import Kinematics
from calib.profile import profile_of
from calib.provenance import provenance
from calib.names import joint_label

from acq.session.rig import c3_setup
from acq.session.setup import setup_robot
from acq.session.store import code_version

from offline.reduction.context import Reduction
from offline.reduction.registry import STAGE_ERRORS, Stage
from offline.reduction.session import SessionData, load_session
from offline.reduction.stages import all_stages


def worded(stage: str, exc: Exception, details: list[str]) -> str:
    """A failed stage in words for the operator: robocal's own errors already say what is wrong; anything else (a
    computation that failed on these readings) is said plainly, its technical cause kept in ``details`` (the JSON's
    ``problem_details``) for whoever maintains robocal, never shown as exception text."""
    if isinstance(exc, RobocalError):
        return f"{stage}: {exc}"
    details.append(f"{stage}: {type(exc).__name__}: {exc}")
    return (f"{stage}: the recorded readings of this stage could not be reduced to estimates (the computation failed "
            f"on them); check that every step of it was recorded, repeat its steps, and send the session file with "
            f"the results JSON to the maintainers if it persists")


def run_stage(ctx: Reduction, stage: Stage) -> None:
    """One stage: its steps, its computation, its output (or its fallback's) kept under its name."""
    steps = ctx.steps_of(stage.procedures)
    if not stage.applies(ctx.profile):
        if steps and not any(s.applies(ctx.profile) for s in all_stages()
                             if s is not stage and set(s.procedures) & set(stage.procedures)):
            ctx.said(f"{stage.words}: does not apply to {ctx.profile.name}: its {len(steps)} steps are not reduced")
        return
    out = None
    try:
        out = stage.run(ctx, steps)
    except STAGE_ERRORS as exc:
        ctx.problems.append(worded(stage.words, exc, ctx.details))
    if out is None and stage.fallback is not None:
        out = stage.fallback(ctx)
    if stage.gives and out is not None:
        ctx.outputs[stage.gives] = out


def migrate_steps(data: SessionData, robot) -> None:
    """Every step's physical set-up in the step vocabulary (masses at points on links, gauges as points with an axis,
    the operator's entered mass applied), once, as the session is read: steps recorded before that vocabulary (a
    force on a lever, gauges along a link) are translated by geometry (:func:`acq.session.rig.c3_setup`), so no
    stage translates them again."""
    kin = Kinematics(robot)
    for st in data.steps:
        spec = st["spec"]
        if spec.get("setup"):
            spec["setup"] = c3_setup(spec["setup"], spec.get("pose_deg"), st["inputs"], kin)


def reduce_for(data: SessionData, output: str) -> Reduction:
    """Only the stages an output needs (``identified``: the model of the pose set, without its held-out accuracy),
    on a session as loaded: what the calibration core gives a running session (ISO 9283's compensated commands).
    The output is ``ctx.outputs.get(output)``; why it is missing is in ``ctx.problems``."""
    ctx = start_reduction(data, held_out=False)
    stages = all_stages()
    by_output = {s.gives: s for s in stages if s.gives}
    wanted, todo = set(), [output]
    while todo:
        s = by_output[todo.pop()]
        if s.name not in wanted:
            wanted.add(s.name)
            todo += list(s.needs)
    for stage in stages:                    # dependency order
        if stage.name in wanted:
            run_stage(ctx, stage)
    return ctx


def start_reduction(data: SessionData, n_mc: int = 0, held_out: bool = True) -> Reduction:
    """The state a reduction of ``data`` starts from: its robot (from the set-up), every step in the step
    vocabulary, nothing reduced yet."""
    robot = setup_robot(data.setup)
    migrate_steps(data, robot)
    return Reduction(data, robot, profile_of(robot), data.setup, n_mc, held_out=held_out)


def reduce_session(session: str | SessionData, n_mc: int = 0, progress=None) -> dict:
    """Reduce every stage of a session (its path, or as loaded); returns the results document (see the module
    docstring)."""
    t0 = time.perf_counter()
    data = load_session(session) if isinstance(session, str) else session
    ctx = start_reduction(data, n_mc)
    for stage in all_stages():
        run_stage(ctx, stage)
        if progress and stage.progress is not None:
            progress(stage.name, stage.progress)
    if progress:
        progress("done", 1.0)
    return results_document(ctx, time.perf_counter() - t0)


def code_provenance(data: SessionData) -> dict:
    """The results' provenance that does not depend on the reduction: the code, the robot description, the command
    (git and the package metadata asked: a reduction while the session records asks them early)."""
    return {**provenance(data.setup.robot or None, None), "code_version": code_version()}


def results_document(ctx: Reduction, elapsed_s: float, code: dict | None = None) -> dict:
    """The results document of a reduction whose every stage has run (see the module docstring); ``code``: its
    :func:`code_provenance`, when asked already."""
    data, robot, n_mc = ctx.data, ctx.robot, ctx.n_mc
    by_proc = data.by_procedure()
    return {
        "session": {"guid": data.session["guid"], "title": data.session["title"], "path": data.path,
                    "exit_status": data.session["exit_status"], "steps_accepted": len(data.steps),
                    "procedures": {name: len(sts) for name, sts in by_proc.items()}},
        "provenance": {**(code or code_provenance(data)), "reprocessed_unix_s": time.time(),
                       "input_session": data.session["guid"], "n_mc": n_mc, "elapsed_s": elapsed_s},
        "estimates": ctx.est.items,
        "bounds": ctx.est.bounds,
        "accuracy": {k: v for k, v in ctx.figs.get("accuracy", {}).items() if not k.endswith(("_err_mm", "_index"))}
        or None,
        "problems": ctx.problems,
        "problem_details": ctx.details,
        "robot": ctx.outputs.get("identified"),
        "iso9283": ctx.outputs.get("iso9283"),      # ISO 9283 AP and RP per pose, compensation off and on
        "joint_labels": [joint_label(robot, j) for j in range(1, robot.n + 1)],   # how reports name the joints
        "figures": ctx.figs,
        "profile": ctx.profile.as_dict(),
        "trace": ctx.trace,
    }
