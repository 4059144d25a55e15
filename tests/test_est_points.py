"""Point coordinates from two sightings (eq 4.3.1, App A.2, B.3)."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.points import point_first_order, point_xyz, points_from_readings
from calib.theodolite import intersect, thesis_readings, thesis_stations
from calib.units import ARCSEC, DEG
from tests.fakes.oracle.chain import numeric_jacobian

L0, G1, G2 = 1609.9, -1.489 * DEG, 1.358 * DEG
PTS = np.array([[500.0, 2500.0, 200.0], [900.0, 2800.0, -300.0], [300.0, 2000.0, 0.0], [1500.0, 1500.0, 800.0]])


def _readings():
    a, b = thesis_stations(L0, G1, G2)
    return thesis_readings(a, b, PTS)


def test_recovers_points_and_matches_the_general_intersection():
    ap, bp, ph = _readings()
    x = np.stack([ap, bp, ph, *np.broadcast_to([[L0], [G1], [G2]], (3, len(PTS)))], -1)
    np.testing.assert_allclose(point_xyz(x), PTS, atol=1e-9)
    a, b = thesis_stations(L0, G1, G2)
    inter = intersect([a, b], [a.observe(PTS), b.observe(PTS)])
    np.testing.assert_allclose(inter.point_mm, PTS, atol=1e-6)


def test_b3_first_order_matches_numerical_jacobian():
    ap, bp, ph = _readings()
    x = np.stack([ap, bp, ph, *np.broadcast_to([[L0], [G1], [G2]], (3, len(PTS)))], -1)
    J = point_first_order(x)
    Jn = numeric_jacobian(point_xyz, x, np.array([1e-7, 1e-7, 1e-7, 1e-4, 1e-7, 1e-7]))
    np.testing.assert_allclose(J, Jn, rtol=1e-5, atol=1e-6)


def test_three_ways_agree_and_points_are_correlated_through_L():
    ap, bp, ph = _readings()
    Ut = np.diag([0.2, 2e-4, 2e-4]) ** 2
    res = points_from_readings(ap, bp, ph, [L0, G1, G2], Ut, 3 * ARCSEC, n_mc=20000, rng=2)
    np.testing.assert_allclose(res.value, PTS.ravel(), atol=1e-8)
    for e in res.estimates():
        assert e.agreement() < 0.10, e
    r = res.correlation()
    assert abs(r[1, 4]) > 0.3                     # Y of two points share the L and gamma errors


def test_bad_sightings_refused():
    ap, bp, ph = _readings()
    with pytest.raises(EstimationError, match="points: eq 4.3.1: sightings of point 1 do not intersect"):
        points_from_readings(ap, np.r_[bp[0], G2 - 0.01, bp[2:]], ph, [L0, G1, G2], np.zeros((3, 3)), 3 * ARCSEC)
    with pytest.raises(EstimationError, match="non-finite"):
        points_from_readings(np.r_[np.nan, ap[1:]], bp, ph, [L0, G1, G2], np.zeros((3, 3)), 3 * ARCSEC)
    with pytest.raises(EstimationError, match="one reading per point"):
        points_from_readings(ap, bp[:2], ph, [L0, G1, G2], np.zeros((3, 3)), 3 * ARCSEC)
    with pytest.raises(EstimationError, match="out of range"):
        points_from_readings(np.degrees(ap), bp, ph, [L0, G1, G2], np.zeros((3, 3)), 3 * ARCSEC)
