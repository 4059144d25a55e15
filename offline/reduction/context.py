"""What every reduction stage works with: the session, the robot and its profile, the set-up, the estimates and
figures collected so far, the problems said, the outputs of earlier stages, and the located targets.

``trace`` keeps, per stage, what an independent check of its estimates needs that is not in the estimates
themselves (the joint readings of the pose set, the torques a stiffness was fitted against ...): the simulation side
(:mod:`sim.emulate.truth`) computes an emulated session's truths from it afterwards.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

from calib.estimators.points import StationFit, TargetPoint, locate_targets, points_covariance
from calib.profile import RobotProfile
from calib.robot import Robot

from acq.session.setup_types import BenchSetup

from offline.reduction.estimates import Estimates
from offline.reduction.session import SessionData

T = TypeVar("T")


def step_ids(steps: list[dict]) -> tuple[int, ...]:
    """The steps by their ``step_id`` (in a :meth:`Reduction.keep` key)."""
    return tuple(s["step_id"] for s in steps)


class Located:
    """Targets of every step intersected with the stations of the session, with covariances that carry the stations'
    fit uncertainty, located one procedure at a time: the first step asked for of a procedure locates every step of
    it read so far in one batch.

    Why by procedure: a batch's intersections share their Gauss-Newton iterations (every point steps until the
    largest step is below 1e-10 mm) and a batch of a few sightings goes through the plain-float code, so a point's
    last bits depend on what else its batch holds.  With one batch per procedure they depend on the procedure's own
    steps only -- the same whether the whole session is reduced at once or while it records (each procedure read
    once it is complete, :mod:`offline.reduction.live`), and whenever its steps are first asked for."""

    def __init__(self, steps: list[dict], station_fit: StationFit):
        self.steps = steps
        self.station_fit = station_fit
        self._by_step: dict[int, dict[str, TargetPoint]] = {}      # by the step's ``step_id``
        self._seen: set[int] = set()

    def __call__(self, step: dict) -> dict[str, TargetPoint]:
        """Target name -> :class:`~calib.estimators.points.TargetPoint` of one step (empty: nothing located)."""
        if step["step_id"] not in self._seen:
            proc = step["procedure"]
            self._locate([s for s in self.steps if s["procedure"] == proc and s["step_id"] not in self._seen])
        return self._by_step.get(step["step_id"], {})

    def _locate(self, steps: list[dict]) -> None:
        rows = [{**r, "target": f"{i}/{r['target']}"} for i, s in enumerate(steps) for r in s["readings"]]
        for key, tp in (locate_targets(rows, self.station_fit) if rows else {}).items():
            i, tg = key.split("/", 1)
            self._by_step.setdefault(steps[int(i)]["step_id"], {})[tg] = tp
        self._seen.update(s["step_id"] for s in steps)

    def covariance(self, points: list[TargetPoint]) -> np.ndarray:
        """Joint covariance of located targets (the stations' common term included)."""
        return points_covariance(points, self.station_fit)


@dataclass
class Reduction:
    """The state of one reduction (see the module docstring)."""

    data: SessionData
    robot: Robot
    profile: RobotProfile
    setup: BenchSetup
    n_mc: int = 0
    held_out: bool = True          # the pose set's held-out accuracy (False: the model alone, for compensation)
    est: Estimates = field(default_factory=Estimates)
    figs: dict = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    details: list[str] = field(default_factory=list)   # technical causes of failed stages: JSON only
    trace: dict = field(default_factory=dict)
    outputs: dict = field(default_factory=dict)
    _located: Located | None = None
    kept: dict = field(default_factory=dict)        # see :meth:`keep`
    # told (name, value, problems so far) when a stage has an output ready before it ends: whoever waits for it (a
    # reduction while the session records: the pose set's model for ISO 9283's compensated run) has it now
    on_output: Callable[[str, object, list[str]], None] | None = None

    def steps_of(self, procedures: tuple[str, ...]) -> list[dict]:
        """The accepted steps of these procedures, in the order recorded."""
        return [st for st in self.data.steps if st["procedure"] in procedures]

    @property
    def points(self) -> Located:
        """The located targets, with the stations the ruler stage gave (``outputs["stations"]``)."""
        if self._located is None:
            self._located = Located(self.data.steps, self.outputs["stations"])
        return self._located

    def keep(self, key: tuple, compute: Callable[[], T]) -> T:
        """``compute()``, kept under ``key`` and reused by whoever asks with the same key.

        Why: a reduction while the session records does part of a stage's work ahead, while the stage still waits for
        the procedures it needs besides its own (a stage module's ``PREPARE``, :mod:`offline.reduction.live`); the
        stage then finds it done.  The stage and ``PREPARE`` ask through the same function, and ``key`` names every
        input the result depends on that may change (the steps by ``step_id``, the geometry's parameters, the
        axis): the rest -- a complete procedure's steps, their located targets, the stations -- does not change once
        read.  So a kept result is the one the stage would compute itself."""
        if key not in self.kept:
            self.kept[key] = compute()
        return self.kept[key]

    def read_again(self, data: SessionData) -> None:
        """The session as it stands now (more steps recorded since ``data`` was read): the reduction so far keeps its
        outputs, estimates and located targets; the new steps' targets are located when first asked for."""
        self.data = data
        if self._located is not None:
            self._located.steps = data.steps

    def gave(self, name: str, value) -> None:
        """Stage output ``name`` is ready before the rest of its stage (see ``on_output``)."""
        if self.on_output is not None:
            self.on_output(name, value, list(self.problems))

    def said(self, text: str) -> None:
        """A problem a stage met on part of its data (the rest of it still counts)."""
        self.problems.append(text)
