"""Chapter 4 estimators of the thesis, one small module per procedure, each with its estimation error three ways.

* :mod:`.ruler` -- theodolite pre-calibration (L, gamma1, gamma2; section 4.2, App A.1, B.1-B.2)
* :mod:`.points` -- point coordinates from two sightings (eq 4.3.1, App A.2, B.3)
* :mod:`.axes` -- joint axes from a swept target: least-squares plane and circle (sections 4.3.1-4.3.2, A.3, B.4-B.5)
* :mod:`.dh` -- DH parameters from successive axes, and the thesis's Puma formulas (eq 4.3.15, B.6)
* :mod:`.transmission` -- joint angle from two tool targets, transmission-error harmonic fit (section 4.4, 5.4)
* :mod:`.compliance` -- joint stiffness, two-slope fit, loading/unloading offset (section 4.5, 5.5)
* :mod:`.link_compliance` -- link flexural rigidity from dial gauges (section 4.6)
* :mod:`.coupling` -- wrist cross-coupling factors (section 4.7, 5.6)
* :mod:`.chain` -- ruler -> points -> axes -> DH as one vectorised function (Monte Carlo of the whole chain)

Results are :class:`calib.uncertainty.EstimateSet` objects (names, values, units, covariances GUM / Monte Carlo /
first order).  Bad input raises :class:`EstimationError` naming the procedure, the step and what is missing.
"""
from ._common import EstimationError

__all__ = ["EstimationError"]
