"""ISO 9283's compensated commands, computed when the session reaches them: the runner's ``command`` hook.

Why at run time: the standard measures the robot moving to the commands a calibrated controller sends, so the
compensated run must really be commanded -- and its commands exist only once there is a calibrated model.  In a
session whose plan has the Chapter 6 pose set before the ISO 9283 runs, the model is the one the calibration core
identifies from the pose set recorded so far (the reduction's own stages, :func:`offline.reduction.run.reduce_for`,
without the held-out accuracy); a model file (``robocal identify``'s model JSON) may be given instead.  Each
command is :func:`calib.compensate.reach` with that model: the joint command that puts the calibrated model's target
on the cube point, reached after the same approach (every joint moving in the positive direction).  The cube's
points are the targets in both runs, so the two runs differ only by the model that computed the command.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from calib.compensate import IdentifiedModel, load_model, model_from_document, points_to_compensate, reach
from calib.effects import PoseContext
from calib.errors import RobocalError

from acq.session.steps import Step

#: the compensated command must put the calibrated model's target this close to the cube point (mm)
COMMAND_TOL_MM = 0.01


class CompensatedCommands:
    """The ``command`` hook of :class:`acq.session.runner.Runner` for ISO 9283's compensated steps.

    ``store``: the session's store (the pose set is read from it when the first compensated step is reached);
    ``model_path``: a calibrated model JSON to use instead.  The model and each pose's command are computed once."""

    def __init__(self, store=None, model_path: str | None = None,
                 identified: Callable[[], dict | None] | None = None):
        self.store = store
        self.model_path = model_path
        # the pose set's model document from the reduction running beside the session (app.live_reduction.
        # SessionReduction.model; None: the pose set gave none); without it, identified here from the store
        self.identified = identified
        self._model: IdentifiedModel | None = None
        self._commands: dict[tuple, tuple[tuple, tuple]] = {}

    def __call__(self, step: Step) -> Step:
        if step.setup.get("command") != "compensated":
            return step
        key = (tuple(step.meta["point_mm"]), tuple(step.pose_deg))
        if key not in self._commands:
            self._commands[key] = self._solve(step)
        q, approach = self._commands[key]
        return replace(step, pose_deg=q, setup={**step.setup, "approach_deg": list(approach)})

    def use(self, model_doc: dict) -> None:
        """Command with this model document (the ``robot`` of a reduction's results: the demo reprocesses its session
        before the compensated run instead of identifying the pose set twice)."""
        self._model = model_from_document(model_doc, "the session's reduction")
        self._commands.clear()

    def model(self) -> IdentifiedModel:
        if self._model is None:
            self._model = load_model(self.model_path) if self.model_path else self._identified()
        return self._model

    def _identified(self) -> IdentifiedModel:
        """The model the calibration core identifies from the session's pose set as recorded so far."""
        if self.identified is not None:
            doc = self.identified()
            if doc is None:
                raise RobocalError("iso9283: no calibrated model to compensate with: the session's pose set gives none "
                                   "(the results' problems say why)")
            return model_from_document(doc, "the session's pose set")
        if self.store is None:
            raise RobocalError("iso9283: no calibrated model: the session has no store to identify one from")
        # the reduction (20 ms of imports) only in a process that reduces: the demo's recorder hands it to a worker
        from offline.reduction.run import reduce_for
        from offline.reduction.session import load_session
        ctx = reduce_for(load_session(str(self.store.path)), "identified")
        doc = ctx.outputs.get("identified")
        if doc is None:
            why = f" ({ctx.problems[0]})" if ctx.problems else ""
            raise RobocalError(f"iso9283: no calibrated model to compensate with: the pose set recorded so far does "
                               f"not identify one{why}")
        return model_from_document(doc, "the session's pose set")

    def _solve(self, step: Step) -> tuple[tuple, tuple]:
        """(command, approach) in degrees for the step's cube point with the calibrated model."""
        im = self.model()
        robot = im.model.robot
        scale = robot.reading_edge_scale
        nominal = np.asarray(step.pose_deg, float) * scale
        offset = nominal - np.asarray(step.setup["approach_deg"], float) * scale          # the approach, per reading
        ctx = PoseContext(1, robot.n, direction=np.ones((1, robot.n)))                    # arriving in + direction
        r, err = reach(im.model, im.theta, _points(im), np.asarray(step.meta["point_mm"], float)[None, None, :],
                       nominal[None], robot.reading_matrix, robot.reading_offset, ctx, iterations=15,
                       tol_mm=COMMAND_TOL_MM / 10)
        if not err[0] < COMMAND_TOL_MM:
            raise RobocalError(f"{step.key}: the calibrated model reaches pose {step.meta['pose']} only within "
                               f"{err[0]:.3g} mm")
        q = robot.reading_matrix @ r[0] + robot.reading_offset
        lim = robot.limits_rad
        if np.any(q < lim[:, 0]) or np.any(q > lim[:, 1]):
            raise RobocalError(f"{step.key}: the compensated command of pose {step.meta['pose']} leaves the joint "
                               "limits")
        cmd = r[0] / scale
        return tuple(round(float(v), 6) for v in cmd), tuple(round(float(v), 6) for v in cmd - offset / scale)


def iso_after_compensated_run(res: dict, db: str) -> None:
    """``res`` (a reduction's results, before the compensated run was recorded) with the ISO 9283 figures of both runs
    and the step counts as the database now holds them: the ruler's stations and the ISO 9283 stage reduced again
    (:func:`offline.reduction.run.reduce_for`), nothing else -- the other stages' steps did not change."""
    # the reduction (20 ms of imports) only in a process that reduces: the demo's recorder hands it to a worker
    from offline.reduction.run import reduce_for
    from offline.reduction.session import load_session
    data = load_session(db, ("ruler", "iso9283"))
    ctx = reduce_for(data, "iso9283")
    res["iso9283"] = ctx.outputs.get("iso9283")
    if "iso9283" in ctx.figs:
        res.setdefault("figures", {})["iso9283"] = ctx.figs["iso9283"]
    res["problems"] = [p for p in res.get("problems", []) if not p.startswith("ISO 9283")] + \
        [p for p in ctx.problems if p.startswith("ISO 9283")]
    done = data.by_procedure()
    procedures = {**res["session"].get("procedures", {}), "iso9283": len(done.get("iso9283", []))}
    res["session"].update(exit_status=data.session["exit_status"], procedures=procedures,
                          steps_accepted=sum(procedures.values()))


def _points(im: IdentifiedModel) -> list[tuple[int, np.ndarray]]:
    """(frame, identified position) of the sighted target: the model's reference tool point."""
    pts = points_to_compensate(im)
    if len(pts) > 1:
        raise RobocalError("iso9283: a robot with several target points: the compensated command needs the sighted "
                           "target's frame (not supported yet)")
    return pts
