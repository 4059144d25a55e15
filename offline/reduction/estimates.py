"""The reduction's answers: estimates (value, 1-sigma error, unit) and one-sided bounds, in the results document's
form.  No truth here: an emulated session's truths are filled in afterwards, from the twin, by the simulation side
(:mod:`sim.emulate.truth`); the reduction never sees them."""
from __future__ import annotations


class Estimates:
    """Collects estimates (``items``) and bounds (``bounds``) in the order the stages give them."""

    def __init__(self) -> None:
        self.items: list[dict] = []
        self.bounds: list[dict] = []

    def add(self, name: str, value: float, error: float, unit: str, held: bool = False, **extra) -> None:
        """One estimate.  ``held``: not estimated -- kept at its design value because the data cannot determine it
        (comparing it with a truth says nothing about the estimation)."""
        self.items.append({"name": name, "value": float(value), "error": float(error), "unit": unit, "truth": None,
                           "held": bool(held), **extra})

    def add_bound(self, name: str, value: float, unit: str, side: str, confidence: float, **extra) -> None:
        """A one-sided bound instead of an estimate (the data show the quantity is beyond what they can resolve):
        kept apart from ``items`` (``bounds`` in the results), since it has no 1-sigma error to compare with."""
        self.bounds.append({"name": name, "value": float(value), "unit": unit, "side": side,
                            "confidence": float(confidence), "truth": None, **extra})

    def add_set(self, prefix: str, es, only=None) -> None:
        """Every estimate of ``es`` (an :class:`calib.uncertainty.EstimateSet`; or those named in ``only``) as
        ``prefix + name``.  One that is another estimate of the set under a second name
        (:meth:`calib.uncertainty.EstimateSet.same_as`) says so in ``same_as`` (and ``same_as_sign``: -1 when the two
        parametrisations have opposite signs), so a count of estimates takes it once."""
        same = es.same_as()
        for e in es.estimates():
            if only is not None and e.name not in only:
                continue
            extra = {}
            if e.name in same and (only is None or same[e.name][0] in only):
                extra = {"same_as": f"{prefix}{same[e.name][0]}", "same_as_sign": same[e.name][1]}
            self.add(f"{prefix}{e.name}", e.value, e.error, e.unit, **extra)

    def named(self, prefix: str) -> dict[str, dict]:
        """The estimates whose name starts with ``prefix``, by the rest of their name."""
        return {e["name"][len(prefix):]: e for e in self.items if e["name"].startswith(prefix)}
