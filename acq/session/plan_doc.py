"""A session's plan as typed data: which procedures, with which parameters -- one JSON Schema for the whole plan
(the session database keeps it as JSON), checked once when a plan enters (:func:`plan_of`), and the parameters'
defaults in one place, the dataclasses below.  A joint list left empty means "the robot profile's"
(:mod:`calib.profile`), which the procedures ask for when they generate the steps.

Angles in degrees (what the operator types into the teach pendant), joints 1-based.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from calib.jsonfile import FINITE, check_schema

_COUNT = {"type": "integer", "minimum": 1, "maximum": 10000}
_JOINTS = {"type": "array", "items": {"type": "integer", "minimum": 1, "maximum": 64}, "uniqueItems": True}


def _obj(properties: dict) -> dict:
    return {"type": "object", "properties": properties, "additionalProperties": False}


@dataclass(frozen=True)
class RulerPlan:
    """The ruler: each placement's marks sighted ``repeats`` times."""

    repeats: int = 1


@dataclass(frozen=True)
class InstrumentCheckPlan:
    """Both instruments on the far target, both faces, ``repeats`` times (collimation and index error)."""

    repeats: int = 2


@dataclass(frozen=True)
class SweepPlan:
    """Each joint's sweep: ``points`` positions over ``span_deg``, ``repeats`` times, on ``joints`` (empty: the
    profile's)."""

    points: int = 4
    span_deg: float = 60.0
    repeats: int = 1
    joints: tuple[int, ...] = ()
    point_p: bool = True             # sight point P (eq 4.3.15's d3) when the robot's profile has the scheme


@dataclass(frozen=True)
class PosesPlan:
    """The pose set (Chapter 6): the joint readings ``q_deg`` of each pose, ``repeats`` times."""

    q_deg: tuple[tuple[float, ...], ...] = ()
    repeats: int = 1


@dataclass(frozen=True)
class TransmissionPlan:
    """The transmission error: ``points`` offsets over each joint's ``range_deg`` about the reference pose,
    ``repeats`` times."""

    joints: tuple[int, ...] = ()
    points: int = 9
    repeats: int = 1
    range_deg: dict[str, tuple[float, float]] = field(default_factory=dict)   # joint -> offsets from READY


@dataclass(frozen=True)
class CompliancePlan:
    """The joint compliance: each loaded joint's load series, ``repeats`` times."""

    joints: tuple[int, ...] = ()     # default: the joints the set-up loads
    repeats: int = 1


@dataclass(frozen=True)
class CouplingPlan:
    """The coupling of each pair (j, k) of ``pairs``: k alone, then j and k together, through ``angle_deg``,
    ``repeats`` times."""

    pairs: tuple[tuple[int, int], ...] = ()
    angle_deg: float = 10.0
    repeats: int = 1


@dataclass(frozen=True)
class ResolutionPlan:
    """The encoder resolution: each of ``joints`` stepped one way through ``span_deg`` in ``points`` steps, A1 and
    A2 sighted, ``repeats`` times."""

    joints: tuple[int, ...] = ()
    points: int = 7
    span_deg: float = 150.0
    repeats: int = 1


@dataclass(frozen=True)
class IsoPose:
    """One pose of the ISO 9283 cube: its name (P1..P5), the commanded point (measurement frame, mm) and the nominal
    joint command that puts the description's tool target there (deg; chosen when the plan was made)."""

    pose: str
    point_mm: tuple[float, float, float]
    q_deg: tuple[float, ...]


@dataclass(frozen=True)
class IsoPlan:
    """ISO 9283 pose accuracy and repeatability (:mod:`acq.session.iso_cube`): ``cycles`` per pose (the standard's
    30), each measurement after a fixed approach move ``approach_deg`` below the command on every joint; ``runs``:
    ``off`` (the nominal command) and ``on`` (the calibrated model's command)."""

    poses: tuple[IsoPose, ...] = ()
    cycles: int = 30
    approach_deg: float = 2.0
    side_mm: float = 0.0
    runs: tuple[str, ...] = ("off", "on")
    model: str = ""                  # a calibrated model JSON for the "on" run ("": the session's pose set's)


#: plan key -> its parameters' type
SECTIONS = {"ruler": RulerPlan, "instrument_check": InstrumentCheckPlan, "sweeps": SweepPlan, "poses": PosesPlan,
            "transmission": TransmissionPlan, "compliance": CompliancePlan, "coupling": CouplingPlan,
            "encoder_resolution": ResolutionPlan, "iso9283": IsoPlan}

PLAN_SCHEMA: dict[str, Any] = {
    "type": "object", "additionalProperties": False,
    "properties": {
        # names of the procedure registry (acq.session.procedures: an unknown one is said there, with the known)
        "procedures": {"type": "array", "items": {"type": "string"}, "uniqueItems": True},
        "seed": {"type": "integer", "minimum": 0},
        "ruler": _obj({"repeats": _COUNT}),
        "instrument_check": _obj({"repeats": _COUNT}),
        "sweeps": _obj({"points": {**_COUNT, "minimum": 2}, "span_deg": {**FINITE, "exclusiveMinimum": 0},
                        "repeats": _COUNT, "joints": _JOINTS, "point_p": {"type": "boolean"}}),
        "poses": _obj({"q_deg": {"type": "array", "items": {"type": "array", "items": FINITE, "minItems": 1}},
                       "repeats": _COUNT}),
        "transmission": _obj({"joints": _JOINTS, "points": {**_COUNT, "minimum": 2}, "repeats": _COUNT,
                              "range_deg": {"type": "object", "propertyNames": {"pattern": "^[0-9]+$"},
                                            "additionalProperties": {"type": "array", "items": FINITE,
                                                                     "minItems": 2, "maxItems": 2}}}),
        "compliance": _obj({"joints": _JOINTS, "repeats": _COUNT}),
        "coupling": _obj({"pairs": {"type": "array", "items": {"type": "array", "items": {"type": "integer",
                                                                                          "minimum": 1},
                                                                  "minItems": 2, "maxItems": 2}},
                          "angle_deg": FINITE, "repeats": _COUNT}),
        "encoder_resolution": _obj({"joints": _JOINTS, "points": {**_COUNT, "minimum": 2},
                                    "span_deg": {**FINITE, "exclusiveMinimum": 0}, "repeats": _COUNT}),
        "iso9283": _obj({"poses": {"type": "array", "minItems": 1, "items": {
                             "type": "object", "additionalProperties": False, "required": ["pose", "point_mm", "q_deg"],
                             "properties": {"pose": {"type": "string"},
                                            "point_mm": {"type": "array", "items": FINITE, "minItems": 3,
                                                         "maxItems": 3},
                                            "q_deg": {"type": "array", "items": FINITE, "minItems": 1}}}},
                         "cycles": {**_COUNT, "minimum": 2}, "approach_deg": {**FINITE, "exclusiveMinimum": 0},
                         "side_mm": {**FINITE, "minimum": 0},
                         "runs": {"type": "array", "items": {"enum": ["off", "on"]}, "uniqueItems": True},
                         "model": {"type": "string"}}),
    },
}


@dataclass(frozen=True)
class SessionPlan:
    """The whole plan (see the module docstring)."""

    procedures: tuple[str, ...] = ()          # in order; a procedure generator alone reads only its own entry
    seed: int = 0
    ruler: RulerPlan = RulerPlan()
    instrument_check: InstrumentCheckPlan = InstrumentCheckPlan()
    sweeps: SweepPlan = SweepPlan()
    poses: PosesPlan = PosesPlan()
    transmission: TransmissionPlan = TransmissionPlan()
    compliance: CompliancePlan = CompliancePlan()
    coupling: CouplingPlan = CouplingPlan()
    encoder_resolution: ResolutionPlan = ResolutionPlan()
    iso9283: IsoPlan = IsoPlan()

    def to_dict(self) -> dict:
        """The plan as JSON data (what the session database keeps)."""
        return asdict(self)


def _tuples(v):
    return tuple(_tuples(x) for x in v) if isinstance(v, (list, tuple)) else v


def _field(name: str, v):
    """A plan entry's field as the dataclass holds it: tuples for lists, ranges per joint, the ISO cube's poses."""
    if name == "range_deg":
        return {j: tuple(r) for j, r in v.items()}
    if name == "poses" and v and isinstance(v[0], dict):
        return tuple(IsoPose(p["pose"], tuple(p["point_mm"]), tuple(p["q_deg"])) for p in v)
    return _tuples(v)


def plan_of(doc: dict | SessionPlan, where: str = "session plan") -> SessionPlan:
    """The typed plan of a plan document, checked against :data:`PLAN_SCHEMA` (one line naming ``where`` and the
    key when it does not follow it); a :class:`SessionPlan` as it is."""
    if isinstance(doc, SessionPlan):
        return doc
    check_schema(doc, PLAN_SCHEMA, where)
    parts = {k: SECTIONS[k](**{f: _field(f, v) for f, v in doc[k].items()}) for k in SECTIONS if k in doc}
    return SessionPlan(tuple(doc.get("procedures", ())), int(doc.get("seed", 0)), **parts)
