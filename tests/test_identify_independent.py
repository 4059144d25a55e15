"""Identification against truth robocal did not make: tool points and theodolite readings from the independent thesis
generator (tests/fakes/thesis_puma.py), intersected and identified by robocal; the estimates must land on the
generator's parameters within their stated errors."""
from importlib import resources

import numpy as np
import pytest

from calib.effects import CrossCoupling, JointCompliance, TransmissionError
from calib.identify import PointObservations, identify
from calib.model import MeasurementModel
from calib.theodolite import intersect, thesis_stations
from calib.units import ARCSEC, DEG
from tests.fakes import thesis_puma as fake
from tests.fakes.thesis_puma import ThesisPuma, base_matrix

PUMA_TOML = resources.files("calib") / "data" / "puma560.toml"
L_MM, GAMMA1, GAMMA2, SIGMA = 1609.9, -1.489 * DEG, 1.358 * DEG, 3 * ARCSEC
BASE = dict(xyz=(474.9, 2853.0, 184.9), yaw=0.4, pitch=0.002, roll=-0.003)
TOOL_MM = (50.0, 0.0, 100.0)


def perturbed_arm(seed: int) -> ThesisPuma:
    """The thesis Puma with Fig 5.10's estimated lengths and seeded misalignments, on a base in front of A and B."""
    rng = np.random.default_rng(seed)
    arm = ThesisPuma.from_toml(PUMA_TOML)
    arm.a_mm[1], arm.a_mm[2], arm.d_mm[1], arm.d_mm[3], arm.d_mm[5] = 431.0, -29.7, 154.5, 432.2, 56.4
    arm.alpha += rng.normal(0.0, 0.15 * DEG, 6)
    arm.theta_offset[1:] += rng.normal(0.0, 0.10 * DEG, 5)
    arm.beta[1] = rng.normal(0.0, 0.05 * DEG)            # joints 2 and 3 are nominally parallel (Hayati)
    arm.base = base_matrix(BASE["xyz"], BASE["yaw"], BASE["pitch"], BASE["roll"])
    arm.tool_xyz_t = tuple(-v for v in TOOL_MM)          # ^6E holds the tool at (-Xt, -Yt, -Zt)
    return arm


def robocal_names(arm: ThesisPuma) -> dict[str, float]:
    """The generator's parameters under robocal's names (the comparison needs a common vocabulary, not code)."""
    t = {f"base.{k}": v for k, v in zip(("x_mm", "y_mm", "z_mm"), BASE["xyz"])}
    t.update({"base.yaw_rad": BASE["yaw"], "base.pitch_rad": BASE["pitch"], "base.roll_rad": BASE["roll"]})
    for j in range(6):
        t.update({f"j{j + 1}.alpha_rad": arm.alpha[j], f"j{j + 1}.a_mm": arm.a_mm[j], f"j{j + 1}.d_mm": arm.d_mm[j],
                  f"j{j + 1}.theta_offset_rad": arm.theta_offset[j], f"j{j + 1}.beta_rad": arm.beta[j]})
    t.update({f"tool.{k}": v for k, v in zip(("x_mm", "y_mm", "z_mm"), TOOL_MM)})
    return t


def poses(rng, robot, n):
    lim = robot.limits_rad
    lo, hi = lim[:, 0] + 10 * DEG, lim[:, 1] - 10 * DEG
    return lo + (hi - lo) * rng.random((n, robot.n))


def sighted_points(points_mm, rng):
    """The generator's readings (eq 4.3.1 inverse) with 3" noise, intersected by robocal's stations."""
    rd = fake.leica_readings(points_mm, L_MM, GAMMA1, GAMMA2) + rng.normal(0.0, SIGMA, (len(points_mm), 4))
    stations = list(thesis_stations(L_MM, GAMMA1, GAMMA2, SIGMA))
    return intersect(stations, [(rd[:, 0], rd[:, 1]), (rd[:, 2], rd[:, 3])])


def gauge_free(res):
    involved = set()
    for c in res.identifiability.unidentifiable:
        involved |= set(c.coefficients)
    return [n for n in res.free if n not in involved]


@pytest.fixture(scope="module")
def puma():
    from calib.loading import load_robot
    return load_robot()


def test_identification_recovers_the_generators_geometry(puma):
    rng = np.random.default_rng(21)
    arm = perturbed_arm(4)
    q = poses(rng, puma, 120)
    pts, _ = fake.true_points(arm, q)
    seen = sighted_points(pts, rng)
    res = identify(MeasurementModel(puma), PointObservations(q, seen.point_mm, seen.cov_mm2))
    truth = robocal_names(arm)
    names = [n for n in gauge_free(res) if n != "j3.d_mm"]
    assert len(names) >= 18
    z = np.array([(res.value(n) - truth[n]) / res.std(n) for n in names])
    assert np.all(np.abs(z) < 4.5), dict(zip(names, z.round(2)))
    for n in ("j2.a_mm", "j3.a_mm", "j4.d_mm"):                     # the Fig 5.10 lengths, far from nominal
        assert abs(res.value(n) - truth[n]) < 0.1 < abs(puma.a_mm[1] - 431.0)
    # Hayati: link 2's d is held and link 3's d carries the shoulder offset
    d1 = res.value("j2.d_mm") - res.value("j3.d_mm")
    assert abs(d1 - truth["j2.d_mm"]) < 4.5 * res.std("j3.d_mm")
    assert 0.7 < res.reduced_chi2 < 1.4
    # held-out poses: the identified model predicts the generator's tool points to the instrument floor
    q2 = poses(rng, puma, 100)
    err = MeasurementModel(puma).points(q2, theta=res.theta) - fake.true_points(arm, q2)[0]
    assert np.sqrt(np.mean(np.sum(err ** 2, 1))) < 0.05


def test_identification_recovers_the_generators_running_errors(puma):
    """Transmission error, one-slope joint compliance under gravity and payload, and wrist coupling, made by the
    generator's own formulas, identified together with the geometry."""
    rng = np.random.default_rng(8)
    arm = perturbed_arm(9)
    n = 240
    q = poses(rng, puma, n)
    payload = np.where(np.arange(n) % 2 == 0, 0.0, 8.0)
    truth_effects = [fake.TransmissionError(4, 0.9, 0.050 * DEG, 0.010 * DEG), fake.JointCompliance(3, 1.3e4),
                     fake.CrossCoupling(6, 5, 0.004)]
    pts, _ = fake.true_points(arm, q, truth_effects, payload)
    seen = sighted_points(pts, rng)
    model = MeasurementModel(puma, [TransmissionError(4, 0.9, [0.0], [0.0]), JointCompliance(3, 1e5),
                                    CrossCoupling(6, 5, 0.0)])
    ctx = model.context(n, payload_kg=payload)
    res = identify(model, PointObservations(q, seen.point_mm, seen.cov_mm2, ctx=ctx))
    expect = {"transmission_error.j4.s1_rad": 0.050 * DEG, "transmission_error.j4.c1_rad": 0.010 * DEG,
              "joint_compliance.j3.compliance1_rad_per_nm": 1 / 1.3e4, "cross_coupling.j5j6.sigma": 0.004}
    for name, v in expect.items():
        assert abs(res.value(name) - v) < 4 * res.std(name), (name, res.value(name), v, res.std(name))
        assert res.std(name) < 0.3 * abs(v), name                  # determined, not just within a huge error
    assert 0.7 < res.reduced_chi2 < 1.4
