"""The bench of an emulated session: it acts on the twin's world (:class:`sim.emulate.twin_world.TwinWorld`) --
the robot to a step's pose, masses at points on links, dial gauges at points -- as an operator acts on a real cell,
and the world's one model does the physics.  The session runtime (:mod:`acq.session.rig`) knows only the
:class:`~acq.session.rig.Bench` it implements.
"""
from __future__ import annotations

import numpy as np

from acq.session.rig import Bench, c3_setup, load_directions
from acq.session.steps import Step, TargetSpec
from calib.kinematics import Kinematics
from calib.loads import hung_masses
from calib.units import DEG

from .twin_world import Target


class EmulatedBench(Bench):
    """Acts on a :class:`sim.emulate.twin_world.TwinWorld`: the demo's robot, loads, targets and dial gauges.

    It only places things -- the robot at the step's pose, masses at points on links, gauges at points -- and the
    world's one model does the physics.  Steps in the vocabulary of contract C3 (``setup["loads"]``,
    ``setup["gauges"]``) are read as they are; older steps (a load ``load_n`` on a lever ``lever_mm`` of joint
    ``joint``; dial gauges at ``gauges_x_mm`` along link ``joint`` with the load at ``load_x_mm``) are first
    translated into the same vocabulary by :func:`c3_setup`.
    """

    def __init__(self, world):
        self.world = world
        self._Target = Target
        self._kin = Kinematics(world.robot)            # the description: what the technician knows

    def prepare(self, step: Step, inputs: dict) -> None:
        w = self.world
        if step.pose_deg is not None:
            if step.setup.get("approach_deg"):      # the approach move first (ISO 9283: one direction)
                w.command(np.asarray(step.setup["approach_deg"], float) * DEG)
            w.command(np.asarray(step.pose_deg, float) * DEG)
        s = c3_setup(step.setup, step.pose_deg, inputs, self._kin)
        w.hang(hung_masses(s.get("loads", [])), load_directions(s, w.robot.n))
        prefetch = getattr(w, "prefetch", None)
        if prefetch is not None:
            prefetch([self._target(t) for t in step.targets])    # the step's targets, at the state it sights them

    def _target(self, target: TargetSpec):
        def tup(v):
            return None if v is None else tuple(float(x) for x in v)
        return self._Target(target.name, tool_mm=tup(target.tool_mm), point_mm=tup(target.point_mm),
                            link=getattr(target, "link", None))

    def aim(self, target: TargetSpec) -> None:
        self.world.aim(self._target(target))

    def read_inputs(self, step: Step) -> dict:
        """What an operator reads off this bench for the step's inputs, by name: the mass it hangs (``load_kg``), the
        force, lever and lever angle of its set-up, its dial gauges.  The bench hangs what the step's set-up says;
        entering it is the operator's act, so a scripted operator enters this, not the plan's hint (tilts are read
        from the instruments, :func:`app.demo.build_demo`)."""
        names = {i.name for i in step.inputs}
        out = {k: float(v) for k, v in step.setup.items() if k in names and isinstance(v, (int, float))}
        loads = c3_setup(step.setup, step.pose_deg, {}, self._kin).get("loads") or []
        if "load_kg" in names and loads:
            out["load_kg"] = float(loads[0]["mass_kg"])
        out.update(self.read_gauges(step, out))
        return out

    def read_gauges(self, step: Step, inputs: dict | None = None) -> dict:
        """What the step's dial gauges show (``<name>_mm``), with the step's loads hung at its pose."""
        s = c3_setup(step.setup, step.pose_deg, inputs or {}, self._kin)
        if not s.get("gauges"):
            return {}
        self.prepare(step, inputs or {})
        return {f"{g['name']}_mm": self.world.gauge_mm(int(g["link"]), g["point_mm"], g["axis"])
                for g in s.get("gauges", [])}
