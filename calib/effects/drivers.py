"""What drives each effect, and whether the data varies it: the one check identify and the diagnosis share.

An effect class names its driver in ``Effect.driven_by`` (a key of :data:`DRIVERS`): the pose condition whose variation
over the poses makes the effect visible -- temperature for thermal drift, time for a drifting instrument, the approach
direction of its joint for backlash, a load for compliance, its joint's own angle for an angle-periodic error.  When
that condition does not vary, the effect's parameters are at best a constant absorbed by the geometry (a thermal
scale at one temperature is a scale of every length), so an estimate of them would be made up from noise: the
identification refuses such an effect in one line, the diagnosis lists it under "not tested", both with the words
:func:`undriven` returns.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .base import Effect, PoseContext

#: a joint that moves less than this over the poses cannot show a joint-angle signature
MIN_RANGE_RAD = 10 * np.pi / 180.0


def _varies(a) -> bool:
    a = np.asarray(a, float)
    return a.size > 0 and bool(np.nanmax(np.ptp(a.reshape(len(a), -1), axis=0)) > 0)


def _temperature(e: Effect, q_rad, ctx: PoseContext, robot) -> str | None:
    return None if _varies(ctx.temperature_c) else "the temperature does not vary over the poses (or is not recorded)"


def _time(e: Effect, q_rad, ctx: PoseContext, robot) -> str | None:
    return None if _varies(ctx.time_s) else "the data carries no time (or it does not vary)"


def _direction(e: Effect, q_rad, ctx: PoseContext, robot) -> str | None:
    if not np.any(ctx.direction != 0):
        return (f"the data carries no approach directions (dir1..dir{ctx.n_joints} columns, or a measurement "
                f"order to infer them from: a time column, --order rows)")
    if _varies(ctx.direction[:, e.joint - 1]):
        return None
    return f"every pose approached joint {e.joint} from the same side (dir{e.joint} constant)"


def _load(e: Effect, q_rad, ctx: PoseContext, robot) -> str | None:
    masses = robot is not None and bool(np.any(np.asarray(robot.mass_kg) > 0))
    forces = any(np.any(np.asarray(a) != 0) for a in (ctx.payload_kg, ctx.tool_force_n, ctx.joint_torque_nm,
                                                       ctx.point_force_n))
    return None if masses or forces else ("the robot description has no masses and the data carries no payload "
                                          "or force")


def _angle_range(joint: int, q_rad, what: str) -> str | None:
    rng = float(np.ptp(np.asarray(q_rad, float)[:, joint - 1])) if len(q_rad) else 0.0
    if rng >= MIN_RANGE_RAD:
        return None
    return (f"joint {joint}{what} moves {np.degrees(rng):.3g} deg over the poses, less than "
            f"{np.degrees(MIN_RANGE_RAD):.0f} deg: no joint-angle signature")


def _joint_angle(e: Effect, q_rad, ctx: PoseContext, robot) -> str | None:
    return _angle_range(e.joint, q_rad, "")


def _source_angle(e: Effect, q_rad, ctx: PoseContext, robot) -> str | None:
    return _angle_range(e.source, q_rad, " (the source of the coupling)")


#: driver name (``Effect.driven_by``) -> check: None when the data varies it, else what is missing, in words
DRIVERS: dict[str, Callable[..., str | None]] = {
    "temperature": _temperature, "time": _time, "direction": _direction, "load": _load,
    "joint_angle": _joint_angle, "source_angle": _source_angle,
}


def undriven(effect: Effect, q_rad, ctx: PoseContext, robot=None) -> str | None:
    """None when the data varies what drives ``effect``; else why nothing drives it (one phrase, no effect name)."""
    check = DRIVERS.get(effect.driven_by) if effect.driven_by else None
    return None if check is None else check(effect, q_rad, ctx, robot)
