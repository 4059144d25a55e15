"""One candidate effect of the diagnosis: an effect kind on a joint, its options and the parameters to estimate.

Its own module because both the library (:mod:`calib.diagnose.candidates`) and the gravity-loaded play grid
(:mod:`calib.diagnose.play`), which the library calls, build candidates: neither imports the other for it.
"""
from __future__ import annotations

from dataclasses import dataclass

from calib.effects import EFFECTS, Effect, make_effect

#: kinds that exclude each other on one joint: one play per joint, plain or gravity-loaded
GROUP_OF = {"backlash_gravity": "backlash"}


@dataclass
class Candidate:
    kind: str                         # one of calib.diagnose.candidates.EFFECT_NAMES
    joint: int | None                 # the joint whose motion the effect disturbs (1-based), None for thermal drift
    source: int | None = None         # cross coupling: the joint whose reading leaks into ``joint``
    order: float | None = None        # transmission error: cycles per radian
    reference_c: float = 20.0         # thermal drift reference temperature
    free: tuple[str, ...] = ()        # parameters to estimate (unqualified names)
    step_s: float = 0.0               # instrument drift: step time (0: a ramp)
    reference_s: float = 0.0          # instrument drift: ramp reference time
    preload_nm: float = 0.0           # gravity-loaded backlash: the torque below which the approach decides
    tool_mass_kg: float = 0.0         # gravity-loaded backlash: lumped end-effector mass at the tool point
    pivot_mm: float = 0.0             # lateral compliance: where on its axis the joint bends (its frame's origin)

    @property
    def group(self) -> tuple:
        """Candidates of one group exclude each other (one transmission error per joint, whatever the order; one
        play per joint, plain or gravity-loaded)."""
        return (GROUP_OF.get(self.kind, self.kind), self.joint, self.source)

    @property
    def label(self) -> str:
        """The finding's name, as the effect kind itself says it (the registry, no branch here)."""
        return self.make().finding_label()

    def make(self) -> Effect:
        """A fresh effect instance at (nearly) zero magnitude: the model's own code gives its Jacobian."""
        order = int(self.order) if self.kind == "axis_tilt" else self.order
        given = {"order": order, "harmonics": 1, "source": self.source, "reference_degc": self.reference_c,
                 "step_s": self.step_s, "reference_s": self.reference_s, "preload_nm": self.preload_nm,
                 "tool_mass_kg": self.tool_mass_kg, "pivot_mm": self.pivot_mm}
        if not EFFECTS[self.kind].has_joint:
            return make_effect(self.kind, **{k: given[k] for k in EFFECTS[self.kind].options})
        return make_effect(self.kind, self.joint, **{k: given[k] for k in EFFECTS[self.kind].options})

    def parameters(self, values: dict[str, float], sigmas: dict[str, float]) -> dict[str, float]:
        """The estimated parameters in edge units (degrees, N m), with their 1-sigma, for reports and JSON."""
        return self.make().edge_parameters(values, sigmas, self.free)
