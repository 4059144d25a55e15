"""What a procedure yields: :class:`Step` -- plain data, so procedures can be listed, previewed and tested.

A step says what the operator must do (``instruction``), where the robot must be (``pose_deg``, joint readings in
degrees), which targets to sight and how (``targets``, ``faces``, ``repeats``), whether to record the encoder stream,
which values the operator must enter (``inputs``: loads, dial-gauge readings) and the physical setup the step needs
(``setup``: a hung load, the ruler mark being sighted).  The runner does the I/O; the procedure never touches a device.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields, is_dataclass


@dataclass(frozen=True)
class InputSpec:
    """A value the operator measures and enters at a step (the load hung, a dial-gauge reading, a tilt).

    Why the plan's value is only a hint: a field pre-filled with the plan lets the operator continue without entering
    what was actually hung, and the reduction then uses a mass nobody checked.  So ``suggested`` (what the procedure
    asks for) is shown beside an empty field, every input must be entered (the runner refuses the step otherwise),
    and an entry more than ``tolerance`` (same unit) from ``suggested`` is a failed check naming both values.
    """

    name: str                       # e.g. "load_n", "gauge1_mm": the unit is in the name and in ``unit``
    unit: str
    prompt: str
    suggested: float | None = None  # the plan's value: a hint, never entered for the operator
    tolerance: float | None = None  # |entered - suggested| beyond this fails the "as planned" check (None: no check)


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
    """One step of a procedure: where the robot stands, what the instruments sight and how often, what the
    operator enters, and the physical state (loads, gauges) the bench is put in."""

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

    def commands(self) -> list:
        """The step in the command vocabulary (:func:`commands`)."""
        return commands(self)

    def spec(self) -> dict:
        """JSON-able record of the step as generated (stored with it): :func:`dataclasses.asdict` of the step (the
        targets and inputs as lists of dicts), built by :func:`_plain` -- the same deep copy without asdict's
        per-leaf ``copy.deepcopy`` calls (a fifth of a step's commit)."""
        d = {name: _plain(getattr(self, name)) for name in _field_names(type(self))}
        d["targets"] = list(d["targets"])
        d["inputs"] = list(d["inputs"])
        return d


_ATOMIC = (str, int, float, bool, type(None))
_ATOMIC_TYPES = frozenset(_ATOMIC)


def _plain(v):
    """:func:`dataclasses.asdict`'s conversion of one value: dataclasses to dicts, lists, tuples and dicts rebuilt
    with their own type, str/int/float/bool/None as they are (what ``copy.deepcopy`` returns for them), anything
    else deep-copied as asdict does.  Plain lists, tuples and dicts (most of a step's setup) are dispatched on their
    exact type first, without the general tests (a step is converted at every commit)."""
    t = type(v)
    if t in _ATOMIC_TYPES:
        return v
    if t is list:
        return [_plain(x) for x in v]
    if t is tuple:
        return tuple([_plain(x) for x in v])
    if t is dict:
        return {_plain(k): _plain(x) for k, x in v.items()}
    if is_dataclass(v) and not isinstance(v, type):
        return {name: _plain(getattr(v, name)) for name in _field_names(t)}
    if isinstance(v, tuple) and hasattr(v, "_fields"):          # a namedtuple: asdict keeps its type
        return type(v)(*[_plain(x) for x in v])
    if isinstance(v, (list, tuple)):
        return type(v)(_plain(x) for x in v)
    if isinstance(v, dict):
        return type(v)((_plain(k), _plain(x)) for k, x in v.items())
    return copy.deepcopy(v)


_FIELD_NAMES: dict[type, tuple[str, ...]] = {}


def _field_names(cls: type) -> tuple[str, ...]:
    """The names of a dataclass's fields, in order (kept per class: ``dataclasses.fields`` builds them each call)."""
    names = _FIELD_NAMES.get(cls)
    if names is None:
        names = _FIELD_NAMES[cls] = tuple(f.name for f in fields(cls))
    return names


# -- the command vocabulary ------------------------------------------------------------------------------------------
# What a step asks of the cell, in order: the runner interprets these in one place (:meth:`Runner._acquire` and the
# setup prompt), the bench (:class:`acq.session.rig.Bench`) performs the physical ones.  A procedure never issues I/O;
# it only fills the step's fields, and :meth:`Step.commands` reads them as commands.
@dataclass(frozen=True)
class Ask:
    """Ask the operator to do the step's instruction and enter ``inputs`` (loads, gauge readings, tilts)."""

    inputs: tuple[InputSpec, ...]


@dataclass(frozen=True)
class Move:
    """The robot to ``pose_deg`` (joint readings, deg)."""

    pose_deg: tuple[float, ...]


@dataclass(frozen=True)
class Hang:
    """Masses at points on links (``{"link", "point_mm", "mass_kg"}``) and the loading direction per joint."""

    loads: tuple
    load_direction: dict


@dataclass(frozen=True)
class ReadGauges:
    """Dial gauges on points of links (``{"name", "link", "point_mm", "axis"}``): the operator enters
    ``<name>_mm``."""

    gauges: tuple


@dataclass(frozen=True)
class Capture:
    """Record the encoder stream while the robot holds still."""


@dataclass(frozen=True)
class Sight:
    """Sight ``target`` with every station, ``repeats`` times on each of ``faces``."""

    target: TargetSpec
    faces: tuple[int, ...]
    repeats: int


def commands(step: Step) -> list:
    """The step as commands, in the order the cell performs them."""
    s = step.setup
    out: list = [Ask(step.inputs)]
    if step.pose_deg is not None:
        if s.get("approach_deg"):                  # a fixed approach: every joint arrives from one direction
            out.append(Move(tuple(s["approach_deg"])))
        out.append(Move(tuple(step.pose_deg)))
    if s.get("loads"):
        ld = s.get("load_direction", {})
        out.append(Hang(tuple(s["loads"]), ld if isinstance(ld, dict) else {}))
    if s.get("gauges"):
        out.append(ReadGauges(tuple(s["gauges"])))
    if step.encoders:
        out.append(Capture())
    out += [Sight(t, step.faces, step.repeats) for t in step.targets]
    return out
