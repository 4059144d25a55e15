"""The emulated truths of the running-error runs come from the twin's parameters by plain formulas, not from the
reduction's estimators on noise-free data: checked against the independent generators of ``tests/fakes`` (the
thesis's loading curve, its transmission error, an encoder's design resolution written out) and numpy's own line
fit -- never against calib.estimators."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim.emulate.truth.runs import resolution_in_estimator_terms, single_slope_truth
from calib.effects import JointCompliance, TransmissionError
from sim.twin import Twin, load_scenario
from calib.units import DEG
from tests.fakes import thesis_procedures as tp

K1, K2, TB, H = 8000.0, 16000.0, 5.0, 2e-4
#: a compliance run as the procedure loads it: up in steps past the breakpoint, then back down
LOADS_NM = np.array([0, 1, 2, 3, 4, 5, 6, 8, 10, 12, 14])
T = np.concatenate([LOADS_NM, LOADS_NM[-2::-1]]).astype(float)
UNLOADING = np.r_[np.zeros(len(LOADS_NM), bool), np.ones(len(LOADS_NM) - 1, bool)]


def _numpy_line(T, unloading, d):
    """The single-slope line through the deflections by numpy's least squares (equal weights)."""
    X = np.stack([np.ones_like(T), unloading.astype(float), T], -1)
    return np.linalg.lstsq(X, d, rcond=None)[0]


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_single_slope_truth_is_the_line_through_the_thesis_loading_curve(sign):
    """One slope over a two-slope joint: the equal-weight line through section 5.5.2's curve (the fake), for a
    torque of either sign; with one slope, the joint's own stiffness and dead zone.  The dead zone follows the load
    direction (unloading gives way back), not the torque's sign: read in the torque's sign, a negative torque's
    unloading branch lies below its loading one (the reduction's offset is ``sign * h``)."""
    effect = JointCompliance(3, K1, K2, TB, H)
    got = single_slope_truth(effect, 3, sign * T, sign, UNLOADING, np.eye(len(T)) * 1e-10)
    b = _numpy_line(T, UNLOADING, tp.two_slope_deflection(T, K1, K2, TB, sign * H, UNLOADING))
    assert got["K1_Nm_per_rad"] == pytest.approx(1.0 / b[2], rel=1e-9)
    assert got["offset_rad"] == pytest.approx(b[1], rel=1e-9, abs=1e-15)
    assert K1 < got["K1_Nm_per_rad"] < K2                      # a mean of the two slopes, not either
    one = single_slope_truth(JointCompliance(3, K1, deadzone_rad=H), 3, sign * T, sign, UNLOADING, 1e-10)
    assert one["K1_Nm_per_rad"] == pytest.approx(K1, rel=1e-9)
    assert one["offset_rad"] == pytest.approx(sign * H, rel=1e-9)


def test_single_slope_truth_follows_the_weights():
    """Which mean of the two slopes one slope is depends on the weights: rows beyond the breakpoint weighted up
    pull it towards K2 -- the same weights as the run's fit, as the truth must use."""
    effect = JointCompliance(3, K1, K2, TB, H)
    w = np.where(T > TB, 1e-12, 1e-10)
    heavy = single_slope_truth(effect, 3, T, 1.0, UNLOADING, w)
    even = single_slope_truth(effect, 3, T, 1.0, UNLOADING, 1e-10)
    X = np.stack([np.ones_like(T), UNLOADING.astype(float), T], -1) / np.sqrt(w)[:, None]
    d = tp.two_slope_deflection(T, K1, K2, TB, H, UNLOADING) / np.sqrt(w)
    assert heavy["K1_Nm_per_rad"] == pytest.approx(1.0 / np.linalg.lstsq(X, d, rcond=None)[0][2], rel=1e-9)
    assert heavy["K1_Nm_per_rad"] > even["K1_Nm_per_rad"]


def test_resolution_truth_is_the_slope_through_the_thesis_transmission_error():
    """The resolution achieved over a run: the line through the encoder angle plus the thesis's transmission error
    (the fake), on the counts; the design resolution written out (2 pi per turn of the motor's encoder)."""
    sc = load_scenario(None)
    r = sc.robot
    design = 2 * np.pi / abs(r.counts_per_rev[5] * r.gear_ratio[5])
    q = np.zeros((7, 6))
    q[:, 5] = np.linspace(0.0, 150.0, 7) * DEG
    counts = np.rint(r.counts_from_joint(q))
    signed = counts[:, 5] * np.sign(r.gear_ratio[5])
    amplitude, order = 0.05 * DEG, 2.0
    te = TransmissionError(6, order, [amplitude], [])
    got = resolution_in_estimator_terms(Twin(dataclasses.replace(sc, effects=[te]), seed=0), 6, counts, signed,
                                        np.eye(7) * 1e-10, design)
    enc = (signed - signed[0]) * design
    true = enc + tp.transmission_truth(enc, amplitude, order)
    slope = np.polyfit(signed - signed[0], true - true[0], 1)[0]
    assert got["rad_per_count"] == pytest.approx(slope, rel=1e-9)
    assert got["scale"] == pytest.approx(slope / design, rel=1e-12)
    assert abs(got["scale"] - 1.0) > 1e-5                      # the transmission error tilts it
    bare = resolution_in_estimator_terms(Twin(dataclasses.replace(sc, effects=[]), seed=0), 6, counts, signed,
                                         np.eye(7) * 1e-10, design)
    assert bare["scale"] == pytest.approx(1.0, abs=1e-9)
