"""Non-geometric effects as composable terms of the one forward model, each with its own named parameters.

An effect acts at one of three stages of the model (see :mod:`calib.model`):

``joint``      adds to the joint angle: ``theta_true = q_reading + sum(delta)``  (transmission error, joint compliance,
               backlash, cross coupling);
``geometry``   changes the kinematic parameters pose by pose (thermal growth of the link lengths);
``point``      displaces the tool point in the measurement frame (link compliance: beam bending under load).

Every effect declares ``param_names`` (with units in the names) and returns its contribution *and* the derivative of
that contribution with respect to its own parameters, so identification, design of experiments and diagnosis get the
full Jacobian from the same code that the twin uses to make its truth.

One module per kind in this package; each class is registered once (:func:`register_effect`) in :data:`EFFECTS`,
and every builder (:mod:`calib.effects.registry`) goes through it.  Adding an effect is one module here (imported
automatically below) plus its tests.  Each kind documents its sign convention in its module.
"""
from __future__ import annotations

import importlib
import pkgutil

from .backlash import Backlash
from .base import EFFECTS, Effect, JointNumber, Loads, PoseContext, register_effect
from .cross_coupling import CrossCoupling
from .joint_compliance import JointCompliance
from .link_compliance import LinkCompliance
from .registry import effect_class, effect_from_spec, effect_from_table, effect_from_text, effect_spec, make_effect
from .thermal_drift import ThermalDrift
from .thesis import THESIS_RUNNING_ERRORS, thesis_effects
from .transmission_error import TransmissionError

# every other module of the package is an effect kind: importing it registers it
for _m in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_m.name}")

__all__ = ["PoseContext", "Loads", "Effect", "EFFECTS", "TransmissionError", "JointCompliance", "Backlash",
           "CrossCoupling", "ThermalDrift", "LinkCompliance", "thesis_effects", "effect_from_text",
           "THESIS_RUNNING_ERRORS", "register_effect", "JointNumber", "make_effect", "effect_class", "effect_spec",
           "effect_from_spec", "effect_from_table"]
