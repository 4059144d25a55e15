"""The reduction's stages, one module each, in the order their estimates are listed (dependencies permitting: see
:func:`offline.reduction.registry.in_order`).  A new stage is a module here defining ``STAGE`` and its name below;
it may define ``PREPARE(ctx, steps)`` too: the part of its work that needs only its own steps, the stations and the
stages already run, kept through :meth:`offline.reduction.context.Reduction.keep` -- a reduction while the session
records runs it as soon as the stage's procedures are complete, while the stage waits for others' outputs
(:mod:`offline.reduction.live`)."""
from __future__ import annotations

from collections.abc import Callable
from importlib import import_module

from offline.reduction.registry import Stage, in_order

MODULES = ("ruler", "sweeps", "misalignment", "compensation", "compliance", "transmission", "poses", "link",
           "coupling", "resolution", "iso9283")


def all_stages() -> list[Stage]:
    """Every stage, in dependency order."""
    return in_order([import_module(f"{__name__}.{m}").STAGE for m in MODULES])


def preparations() -> dict[str, Callable]:
    """Stage name -> its module's ``PREPARE``, for the stages that have one."""
    mods = [import_module(f"{__name__}.{m}") for m in MODULES]
    return {m.STAGE.name: m.PREPARE for m in mods if getattr(m, "PREPARE", None) is not None}
