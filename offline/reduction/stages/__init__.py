"""The reduction's stages, one module each, in the order their estimates are listed (dependencies permitting: see
:func:`offline.reduction.registry.in_order`).  A new stage is a module here defining ``STAGE`` and its name below."""
from __future__ import annotations

from importlib import import_module

from offline.reduction.registry import Stage, in_order

MODULES = ("ruler", "sweeps", "misalignment", "compensation", "compliance", "transmission", "poses", "link",
           "coupling", "resolution", "iso9283")


def all_stages() -> list[Stage]:
    """Every stage, in dependency order."""
    return in_order([import_module(f"{__name__}.{m}").STAGE for m in MODULES])
