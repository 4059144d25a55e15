"""Hung masses as point forces: the one place a mass hung at a point on a link becomes the force the model's loads
take (its weight, mass times the description's gravity in the measurement frame).  The emulated world, the
reduction's torques and the gauges' design all go through :func:`point_force_context`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class HungMass:
    """A mass hung at a point fixed in frame ``link`` (0 base, j = link j): its weight pulls straight down there."""

    link: int
    point_mm: tuple[float, float, float]
    mass_kg: float


def hung_masses(loads: list[dict]) -> list[HungMass]:
    """The step vocabulary's loads (``{"link", "point_mm", "mass_kg"}``) as :class:`HungMass`."""
    return [HungMass(int(ld["link"]), tuple(float(x) for x in ld["point_mm"]), float(ld["mass_kg"])) for ld in loads]


def point_force_context(masses, gravity_n_per_kg: np.ndarray) -> dict:
    """The :class:`calib.effects.PoseContext` keywords of one pose carrying ``masses`` as point forces:
    ``point_force_link`` (K,), ``point_force_mm`` (1, K, 3) in their frames and ``point_force_n`` (1, K, 3) in the
    measurement frame (``gravity_n_per_kg``: :meth:`calib.model.MeasurementModel.gravity_n_per_kg`)."""
    ms = list(masses)
    g = np.asarray(gravity_n_per_kg, float)
    return {"point_force_link": np.array([m.link for m in ms], int),
            "point_force_mm": np.array([[m.point_mm for m in ms]], float).reshape(1, len(ms), 3),
            "point_force_n": np.array([[m.mass_kg * g for m in ms]], float).reshape(1, len(ms), 3)}
