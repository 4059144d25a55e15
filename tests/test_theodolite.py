"""Theodolite geometry: readings of a point, and the point back from readings."""
import numpy as np
import pytest

from calib.errors import GeometryError
from calib.theodolite import (Station, closest_point, intersect, thesis_point, thesis_readings,
                              thesis_stations)
from calib.units import ARCSEC, DEG


def random_points(rng, n=100):
    return np.column_stack([rng.uniform(-500, 2100, n), rng.uniform(800, 4000, n), rng.uniform(-900, 900, n)])


def imperfect_stations():
    a = Station("A", 0, 0, 0, yaw_rad=0.3, tilt_x_rad=4e-5, tilt_y_rad=-2e-5, collimation_rad=15 * ARCSEC,
                trunnion_rad=8 * ARCSEC, index_rad=-12 * ARCSEC)
    b = Station("B", 1650, 40, 25, yaw_rad=2.6, tilt_x_rad=-3e-5, collimation_rad=-9 * ARCSEC,
                trunnion_rad=5 * ARCSEC, index_rad=20 * ARCSEC)
    return a, b


@pytest.mark.parametrize("faces", [(1, 1), (2, 1), (2, 2)])
def test_intersection_round_trip_without_noise(rng, faces):
    pts = random_points(rng)
    a, b = imperfect_stations()
    readings = [a.observe(pts, faces[0]), b.observe(pts, faces[1])]
    out = intersect([a, b], readings, faces=list(faces))
    np.testing.assert_allclose(out.point_mm, pts, atol=1e-9)
    assert np.all(out.miss_mm < 1e-6)


def test_thesis_closed_form_round_trip(rng):
    L, g1, g2 = 1609.9, -1.489 * DEG, 1.358 * DEG
    a, b = thesis_stations(L, g1, g2)
    pts = random_points(rng)
    al, be, ph = thesis_readings(a, b, pts)
    np.testing.assert_allclose(thesis_point(al, be, ph, L, g1, g2), pts, atol=1e-9)


def test_thesis_eq_4_3_1_in_tangent_form(rng):
    """The sine form used in code equals X = L tan b / (tan a + tan b), Y = X tan a, Z = sqrt(X^2+Y^2) tan phi."""
    al = rng.uniform(0.2, 1.3, 20)
    be = rng.uniform(0.2, 1.3, 20)
    ph = rng.uniform(-0.3, 0.3, 20)
    L = 1500.0
    X = L * np.tan(be) / (np.tan(al) + np.tan(be))
    Y = X * np.tan(al)
    Z = np.hypot(X, Y) * np.tan(ph)
    np.testing.assert_allclose(thesis_point(al, be, ph, L, 0.0, 0.0), np.column_stack([X, Y, Z]), atol=1e-9)


def test_covariance_matches_monte_carlo(rng):
    a, b = thesis_stations(1609.9, 0.01, -0.02, sigma_rad=3 * ARCSEC)
    p = np.array([[800.0, 2800.0, 200.0]])
    clean = [a.observe(p), b.observe(p)]
    n = 4000
    draws = [(np.repeat(h, n) + rng.normal(0, 3 * ARCSEC, n), np.repeat(v, n) + rng.normal(0, 3 * ARCSEC, n))
             for h, v in clean]
    out = intersect([a, b], draws)
    mc = np.cov(out.point_mm.T)
    predicted = out.cov_mm2[0]
    np.testing.assert_allclose(np.sqrt(np.diag(mc)), np.sqrt(np.diag(predicted)), rtol=0.08)


def test_observe_jacobian_matches_finite_differences(rng):
    pts = random_points(rng, 10)
    for s in imperfect_stations():
        for face in (1, 2):
            _, _, J = s.observe(pts, face, with_jacobian=True)
            for k in range(3):
                d = np.zeros(3)
                d[k] = 1e-4
                hp, vp = s.observe(pts + d, face)
                hm, vm = s.observe(pts - d, face)
                np.testing.assert_allclose(J[:, 0, k], np.angle(np.exp(1j * (hp - hm))) / 2e-4, atol=1e-9)
                np.testing.assert_allclose(J[:, 1, k], (vp - vm) / 2e-4, atol=1e-9)


def test_face_two_reads_half_turn_and_complement():
    a, _ = imperfect_stations()
    p = np.array([[500.0, 2000.0, 300.0]])
    a0 = Station("A", yaw_rad=0.3)
    h1, v1 = a0.observe(p, 1)
    h2, v2 = a0.observe(p, 2)
    assert np.angle(np.exp(1j * (h2 - h1 - np.pi)))[0] == pytest.approx(0.0, abs=1e-12)
    assert (v1 + v2)[0] == pytest.approx(2 * np.pi)
    # index error: (V_I + V_II - 360) / 2 recovers it
    k = 20 * ARCSEC
    ak = Station("A", yaw_rad=0.3, index_rad=k)
    assert ((ak.observe(p, 1)[1] + ak.observe(p, 2)[1] - 2 * np.pi) / 2)[0] == pytest.approx(k)


def test_parallel_sightings_are_refused():
    a, b = thesis_stations(1600.0, 0.0, 0.0)
    c = a.position
    u = np.array([[0.0, 1.0, 0.0]])
    with pytest.raises(GeometryError, match="parallel"):
        closest_point(c, u, b.position, u)


def test_point_behind_a_station_is_refused():
    a, b = thesis_stations(1600.0, 0.0, 0.0)
    # B looks away from where A's line goes
    with pytest.raises(GeometryError, match="behind station B"):
        closest_point(a.position, np.array([[0.6, 0.8, 0.0]]), b.position, np.array([[0.6, -0.8, 0.0]]))


def test_thesis_point_refuses_a_non_triangle():
    with pytest.raises(GeometryError, match="do not intersect"):
        thesis_point(np.array([1.6]), np.array([1.6]), np.array([0.0]), 1600.0, 0.0, 0.0)


def test_point_on_vertical_axis_is_refused():
    a, _ = thesis_stations(1600.0, 0.0, 0.0)
    with pytest.raises(GeometryError, match="vertical axis"):
        a.observe(np.array([[0.0, 0.0, 500.0]]))


@pytest.mark.parametrize("n", [1, 2, 4])
def test_few_points_in_plain_floats_equal_the_vectorised_intersection(rng, monkeypatch, n):
    """A few points (the session's per-step checks) are intersected in plain floats: the same start, model,
    derivatives, weights and stopping rule as the vectorised loop, so the same point, residuals and covariance to
    rounding, with faces per station or per point, two or three stations."""
    import calib.theodolite as theo
    a, b = imperfect_stations()
    c = Station("C", 800, -900, 300, yaw_rad=1.2, sigma_v_rad=2 * ARCSEC)
    for trial in range(40):
        sts = [a, b, c][: 2 + trial % 2] if n < 4 else [a, b]
        pts = random_points(rng, n)
        faces = [int(rng.integers(1, 3)) for _ in sts]
        if trial % 5 == 0:
            faces[0] = rng.integers(1, 3, n)
        readings = [tuple(x + rng.normal(0, 5 * ARCSEC, n) for x in s.observe(pts, f)) for s, f in zip(sts, faces)]
        few = intersect(sts, readings, faces=faces)
        monkeypatch.setattr(theo, "SMALL_SIGHTINGS", 0)
        full = intersect(sts, readings, faces=faces)
        monkeypatch.undo()
        np.testing.assert_allclose(few.point_mm, full.point_mm, rtol=0, atol=1e-9)
        np.testing.assert_allclose(few.residual_rad, full.residual_rad, rtol=0, atol=1e-13)
        np.testing.assert_allclose(few.cov_mm2, full.cov_mm2, rtol=1e-10, atol=1e-12 * np.abs(full.cov_mm2).max())
        np.testing.assert_allclose(few.miss_mm, full.miss_mm, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(few.angle_rad, full.angle_rad, rtol=0, atol=1e-13)


def test_few_points_refuse_as_the_vectorised_intersection(monkeypatch):
    """The plain-float path refuses what closest_point refuses, with the same words; non-finite readings go to the
    vectorised code."""
    import calib.theodolite as theo
    a, b = imperfect_stations()
    p = np.array([[800.0, 2800.0, 200.0]])
    (ha, va), rb = a.observe(p), b.observe(p)
    cases = [[(ha + np.pi, va), rb], [(ha, va), (ha, va)], [(np.array([np.nan]), va), rb]]
    for readings in cases:
        got = []
        for small in (12, 0):
            monkeypatch.setattr(theo, "SMALL_SIGHTINGS", small)
            try:
                got.append(np.round(intersect([a, b], readings).point_mm, 6).tolist())
            except GeometryError as exc:
                got.append(str(exc))
        assert got[0] == got[1] or np.all(np.isnan(got[0])) and np.all(np.isnan(got[1]))


def test_one_point_readings_are_the_vectorised_ones_bit_for_bit(rng):
    """One point (an emulated theodolite's target) is observed in plain floats: the same readings, bit for bit, as
    the vectorised code gives for a one-point list; the refusal of a point on the vertical axis stays."""
    for _ in range(300):
        st = Station("S", *rng.normal(size=3) * 500, yaw_rad=rng.uniform(-4, 4), tilt_x_rad=rng.normal() * 1e-4,
                     tilt_y_rad=rng.normal() * 1e-4, collimation_rad=rng.normal() * 20 * ARCSEC,
                     trunnion_rad=rng.normal() * 10 * ARCSEC, index_rad=rng.normal() * 20 * ARCSEC)
        p = rng.normal(size=(1, 3)) * 2000
        face = int(rng.integers(1, 3))
        one, ref = st.observe(p, face), st.observe(p.tolist(), face)
        assert one[0].shape == one[1].shape == (1,)
        assert one[0][0] == ref[0][0] and one[1][0] == ref[1][0]
    with pytest.raises(GeometryError, match="on its vertical axis"):
        Station("A", 10.0, 20.0, 0.0).observe(np.array([[10.0, 20.0, 500.0]]))


def test_face_mean_of_a_few_readings_is_numpys_bit_for_bit(rng):
    """Up to seven readings (a target in both faces, repeated) are averaged in plain floats: the very floats of the
    numpy code (Hz wrapped about the first reading, face II reduced), also across the 0/360 deg seam; eight and
    more go through numpy (its pairwise summation adds them in another order)."""
    from calib.angles import wrap_angle
    from calib.theodolite import face_mean

    def numpy_mean(hz, v, face):
        hz, v, face = (np.asarray(a, float) for a in (hz, v, face))
        hz1 = np.where(face == 2, hz - np.pi, hz)
        v1 = np.where(face == 2, 2 * np.pi - v, v)
        return float(np.mod(hz1[0] + np.mean(wrap_angle(hz1 - hz1[0])), 2 * np.pi)), float(np.mean(v1))

    for i in range(9000):
        n = 1 + i % 9
        hz, v, face = rng.uniform(0, 2 * np.pi, n), rng.uniform(0.5, 5.5, n), rng.integers(1, 3, n)
        if n >= 2 and i % 3 == 0:       # the same direction read in both faces, near the seam
            hz[0] = rng.uniform(-1e-5, 1e-5) % (2 * np.pi)
            hz[1:] = (hz[0] + np.pi * (face[1:] != face[0]) + rng.normal(size=n - 1) * 1e-5) % (2 * np.pi)
        assert face_mean(hz, v, face) == numpy_mean(hz, v, face)
        assert face_mean(hz.tolist(), v.tolist(), face.tolist()) == numpy_mean(hz, v, face)


@pytest.mark.parametrize("small", [12, 0])
def test_a_looser_step_tolerance_stops_earlier_within_a_nanometre(rng, monkeypatch, small):
    """``step_tol_mm``: the default is the rounding rule (the reduction's points bit for bit); the session checks'
    1e-6 mm saves the iteration that only confirmed convergence and leaves each point within 1e-9 mm of the
    converged one (the step not taken), on the plain-float path and the vectorised one alike."""
    import calib.theodolite as theo
    from acq.session.checks import CHECK_STEP_TOL_MM
    monkeypatch.setattr(theo, "SMALL_SIGHTINGS", small)
    counts = {}
    for name in ("_normal_equations", "_residuals"):
        real = getattr(theo, name)
        monkeypatch.setattr(theo, name, lambda *a, _r=real, _n=name: counts.__setitem__(_n, counts.get(_n, 0) + 1)
                            or _r(*a))
    a, b = imperfect_stations()
    saved = 0
    for _ in range(30):
        pts = random_points(rng, 2)
        readings = [tuple(x + rng.normal(0, 5 * ARCSEC, 2) for x in s.observe(pts)) for s in (a, b)]
        ref, same = intersect([a, b], readings), intersect([a, b], readings, step_tol_mm=1e-10)
        assert np.array_equal(ref.point_mm, same.point_mm) and np.array_equal(ref.cov_mm2, same.cov_mm2)
        counts.clear()
        intersect([a, b], readings)
        tight = dict(counts)
        counts.clear()
        loose = intersect([a, b], readings, step_tol_mm=CHECK_STEP_TOL_MM)
        assert sum(counts.values()) <= sum(tight.values())
        saved += sum(tight.values()) - sum(counts.values())
        np.testing.assert_allclose(loose.point_mm, ref.point_mm, rtol=0, atol=1e-9)
        np.testing.assert_allclose(loose.cov_mm2, ref.cov_mm2, rtol=1e-6)
        np.testing.assert_array_equal(loose.miss_mm, ref.miss_mm)
    assert saved > 0
