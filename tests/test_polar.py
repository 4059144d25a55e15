"""Polar readings (laser tracker / total station) as points with their own covariance."""
import numpy as np

from calib.polar import PolarNoise, polar_points
from calib.units import ARCSEC, DEG


def test_polar_point_matches_the_theodolite_convention():
    """A station at the origin, levelled, circle zero on +x, reads the point back (Hz clockwise, V zenith)."""
    from calib.theodolite import Station
    rng = np.random.default_rng(2)
    p = rng.uniform(-3000, 3000, (20, 3))
    s = Station("T")
    hz, v = s.observe(p, 1)
    got, _ = polar_points(np.column_stack([hz, v, np.linalg.norm(p, axis=1)]), PolarNoise())
    np.testing.assert_allclose(got, p, atol=1e-9)


def test_covariance_matches_a_monte_carlo_of_the_noise_model():
    rng = np.random.default_rng(4)
    reading = np.array([[30 * DEG, 80 * DEG, 5000.0]])
    noise = PolarNoise(2 * ARCSEC, 0.05, 2.0)
    _, cov = polar_points(reading, noise)
    sd = noise.sigma_dist_mm + noise.ppm * 1e-6 * 5000.0
    draws = reading + rng.normal(0, 1, (40000, 3)) * [noise.sigma_angle_rad, noise.sigma_angle_rad, sd]
    pts, _ = polar_points(draws, noise)
    # sampling error of a covariance entry: about sqrt(C_ii C_jj / n) = 1.5e-5 mm^2 here; 5 of those allowed
    tol = 5 * np.sqrt(np.outer(np.diag(cov[0]), np.diag(cov[0])) / len(draws))
    assert np.all(np.abs(np.cov(pts.T) - cov[0]) < tol)
