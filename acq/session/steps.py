"""What a procedure yields: :class:`Step` -- plain data, so procedures can be listed, previewed and tested.

A step says what the operator must do (``instruction``), where the robot must be (``pose_deg``, joint readings in
degrees), which targets to sight and how (``targets``, ``faces``, ``repeats``), whether to record the encoder stream,
which values the operator must enter (``inputs``: loads, dial-gauge readings) and the physical setup the step needs
(``setup``: a hung load, the ruler mark being sighted).  The runner does the I/O; the procedure never touches a device.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

#: the Puma's READY pose (joint readings, deg): the reference of the sweeps, coupling runs and most loads
READY_DEG = (0.0, -90.0, 90.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class InputSpec:
    """A value the operator enters at a step (e.g. the load hung, a dial-gauge reading)."""

    name: str                       # e.g. "load_n", "gauge1_mm": the unit is in the name and in ``unit``
    unit: str
    prompt: str
    suggested: float | None = None  # what the procedure asked for (the scripted operator enters the measured value)


@dataclass(frozen=True)
class TargetSpec:
    """A target to sight: on the robot (``tool_mm`` in frame ``link``; default the flange frame n) or fixed in the
    measurement frame (``point_mm``, known only for emulated setups: a real ruler mark is simply "mark C")."""

    name: str
    tool_mm: tuple[float, float, float] | None = None
    point_mm: tuple[float, float, float] | None = None
    link: int | None = None


@dataclass(frozen=True)
class Step:
    key: str                                   # unique and stable within a session (resume matches on it)
    procedure: str
    title: str
    instruction: str
    pose_deg: tuple[float, ...] | None = None  # joint readings the robot must hold (None: does not matter)
    targets: tuple[TargetSpec, ...] = ()
    faces: tuple[int, ...] = (1, 2)
    repeats: int = 1
    encoders: bool = True                      # record and check the encoder stream at this step
    inputs: tuple[InputSpec, ...] = ()
    setup: dict = field(default_factory=dict)  # physical state: joint_torque_nm, load_direction, gauges ...
    meta: dict = field(default_factory=dict)   # procedure bookkeeping: joint, index, phase ...

    def spec(self) -> dict:
        """JSON-able record of the step as generated (stored with it)."""
        d = asdict(self)
        d["targets"] = [asdict(t) for t in self.targets]
        d["inputs"] = [asdict(i) for i in self.inputs]
        return d
