"""Every way of building an effect from its kind name goes through here (and so through :data:`EFFECTS`).

* :func:`make_effect` — at zero magnitude from its structure (identification, diagnosis candidates);
* :func:`effect_from_text` — the ``--effect kind:args`` text of ``robocal identify``;
* :func:`effect_spec` / :func:`effect_from_spec` — the ``effects`` entries of the model JSON;
* :func:`effect_from_table` — a scenario file's ``[[effect]]`` table.

A kind the registry does not know is one :class:`RobocalError` line listing the known kinds.
"""
from __future__ import annotations

from typing import Any

from ..errors import RobocalError
from ..tomlspec import Checker, Field
from .base import EFFECTS, Effect, JointNumber
from ..names import joint_names, joint_number

#: keys every ``[[effect]]`` table has besides the kind's own
COMMON_FIELDS = {"type": Field("str", required=True), "enabled": Field("bool", default=True)}


def known_kinds() -> str:
    return ", ".join(EFFECTS)


def effect_class(kind: Any, where: str) -> type[Effect]:
    """The registered class of ``kind``; an unknown kind is one line naming ``where`` and the known kinds."""
    if not isinstance(kind, str) or kind not in EFFECTS:
        raise RobocalError(f"{where}: unknown kind {kind!r} (known: {known_kinds()})")
    return EFFECTS[kind]


def make_effect(kind: str, joint: int | None = None, **options) -> Effect:
    """An effect of ``kind`` at zero magnitude with the given structure (order, source joint, ...)."""
    return effect_class(kind, "effect").zero(joint, **options)


def _joint_keys(cls: type[Effect]) -> list[str]:
    """The keys of ``cls`` that name a joint."""
    return (["joint"] if cls.has_joint else []) + [k for k, t in cls.options.items() if t is JointNumber]


def effect_from_text(text: str, n_joints: int = 6, robot=None) -> Effect:
    """An effect to identify, from a short spec ``kind[:joint][:option...]`` (initial values zero or nominal):

    ``transmission_error:J:ORDER[:HARMONICS]``, ``joint_compliance:J``, ``backlash:J``, ``cross_coupling:J:SOURCE``,
    ``link_compliance:J``, ``thermal_drift[:REFERENCE_DEGC]``.  A joint is its number or, with ``robot``, its name
    as the output shows it (``joint_compliance:arm_6_joint``, :mod:`calib.names`).
    """
    kind, *args = text.split(":")
    cls = effect_class(kind, f"effect {text!r}")
    names = (["joint"] if cls.has_joint else []) + list(cls.options)
    lo, hi = int(cls.has_joint) + cls.text_required, len(names)
    if not lo <= len(args) <= hi:
        raise RobocalError(f"effect {text!r}: {kind} takes {lo if lo == hi else f'{lo} to {hi}'} field(s) after "
                           f"the kind")
    joint_keys = _joint_keys(cls)
    given = {key: _field(text, key, a, key in joint_keys, robot) for key, a in zip(names, args)}
    for key in _joint_keys(cls):
        v = given.get(key)
        if v is not None and (v != int(v) or not 1 <= v <= n_joints):
            raise RobocalError(f"effect {text!r}: joint must be 1..{n_joints}, got {v:g}")
    kw = {k: (v if cls.options.get(k, int) is float else int(v)) for k, v in given.items()}
    try:
        return cls.zero(**kw)
    except ValueError as exc:
        raise RobocalError(f"effect {text!r}: {exc}") from None


def _field(text: str, key: str, raw: str, is_joint: bool, robot) -> float:
    """One ``--effect`` field as a number; a joint field may name the joint."""
    try:
        return float(raw)
    except ValueError:
        pass
    if is_joint and robot is not None:
        j = joint_number(robot, raw)
        if j is None:
            raise RobocalError(f"effect {text!r}: {key} {raw!r} is not a joint of the robot (joints: "
                               f"{', '.join(joint_names(robot))})")
        return float(j)
    raise RobocalError(f"effect {text!r}: fields must be numbers" + (" or joint names" if is_joint else ""))


def effect_spec(e: Effect) -> dict:
    """The structure of ``e`` for the model JSON (its parameter values travel separately, by qualified name)."""
    return {"type": e.kind, "joint": e.joint, **e.option_values()}


def effect_from_spec(spec: dict, values: dict[str, float], where: str) -> Effect:
    """The effect of a model JSON entry, its parameters taken from ``values`` (qualified name -> value)."""
    kind = spec.get("type") if isinstance(spec, dict) else None
    cls = effect_class(kind, where)
    try:
        joint = int(spec["joint"]) if cls.has_joint else None
        e = cls.zero(joint, **{k: t(spec[k]) for k, t in cls.options.items()})
    except (KeyError, TypeError, ValueError) as exc:
        raise RobocalError(f"{where}: effect {kind!r} is missing or has a bad field ({exc})") from None
    for i, name in enumerate(e.qualified_names()):
        if name not in values:
            raise RobocalError(f"{where}: parameter {name} is missing")
        e.values[i] = values[name]
    return e


def effect_from_table(raw: Any, chk: Checker, key: str, n_joints: int) -> tuple[Effect, bool]:
    """The effect of a scenario's ``[[effect]]`` table (checked against the kind's fields) and whether it is on."""
    if not isinstance(raw, dict) or "type" not in raw:
        chk.fail(f"{key}.type", f"missing (one of {known_kinds()})")
    kind = raw["type"]
    if not isinstance(kind, str) or kind not in EFFECTS:
        chk.fail(f"{key}.type", f"unknown kind {kind!r} (known: {known_kinds()})")
    cls = EFFECTS[kind]
    c = chk.table(raw, {**COMMON_FIELDS, **cls.scenario_fields}, key)
    for jkey in _joint_keys(cls):
        if c.get(jkey) is not None and not 1 <= c[jkey] <= n_joints:
            chk.fail(f"{key}.{jkey}", f"must be a joint number 1..{n_joints}, got {c[jkey]}")
    return cls.from_table(c), c["enabled"]
