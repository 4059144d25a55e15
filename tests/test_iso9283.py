"""ISO 9283 AP/RP and the test cube, against the standard's formulas worked by hand (statistics module, plain sums)."""
import math
import statistics

import numpy as np
import pytest

from calib.iso9283 import CYCLES, cube_points, pose_figures


def test_pose_figures_by_hand():
    command = (100.0, 200.0, 300.0)
    attained = [(100.3, 200.1, 299.9), (100.1, 200.2, 300.1), (100.2, 199.9, 300.0), (100.4, 200.0, 300.2)]
    n = len(attained)
    bary = [sum(p[i] for p in attained) / n for i in range(3)]
    ap = math.sqrt(sum((bary[i] - command[i]) ** 2 for i in range(3)))
    l = [math.dist(p, bary) for p in attained]
    rp = statistics.mean(l) + 3 * statistics.stdev(l)
    f = pose_figures("P1", command, attained)
    assert f.ap_mm == pytest.approx(ap, abs=1e-12)
    assert f.apx_mm == pytest.approx(bary[0] - 100.0, abs=1e-12)
    assert f.rp_mm == pytest.approx(rp, abs=1e-12)
    assert f.n == 4


def test_figures_recover_a_known_bias_and_spread():
    """30 cycles of a robot off by (0.3, -0.4, 0) mm with 0.02 mm isotropic scatter: AP near 0.5 mm; RP near the
    mean plus three deviations of a Maxwell distance (sigma * (2 sqrt(2/pi) + 3 sqrt(3 - 8/pi)))."""
    rng = np.random.default_rng(1)
    aps, rps = [], []
    for _ in range(200):
        x = np.array([10.0, 20.0, 30.0]) + [0.3, -0.4, 0.0] + rng.normal(0, 0.02, (CYCLES, 3))
        f = pose_figures("P1", [10.0, 20.0, 30.0], x)
        aps.append(f.ap_mm)
        rps.append(f.rp_mm)
    assert np.mean(aps) == pytest.approx(0.5, abs=0.002)
    maxwell = 0.02 * (2 * math.sqrt(2 / math.pi) + 3 * math.sqrt(3 - 8 / math.pi))
    assert np.mean(rps) == pytest.approx(maxwell, rel=0.05)


def test_cube_points_follow_the_standard():
    c, s = np.array([500.0, 0.0, 400.0]), 200.0
    pts = cube_points(c, s)
    assert list(pts) == ["P1", "P2", "P3", "P4", "P5"]
    np.testing.assert_allclose(pts["P1"], c)
    diag = s * math.sqrt(3)                                  # the diagonal of the diagonal plane (s by s*sqrt 2)
    for k in ("P2", "P3", "P4", "P5"):
        assert np.linalg.norm(pts[k] - c) == pytest.approx(diag / 2 - 0.1 * diag)
    np.testing.assert_allclose(pts["P2"] + pts["P4"], 2 * c)     # opposite corners of one diagonal
    np.testing.assert_allclose(pts["P3"] + pts["P5"], 2 * c)
    normal = np.cross(pts["P3"] - pts["P2"], pts["P5"] - pts["P2"])
    assert abs(np.dot(normal, pts["P4"] - pts["P2"])) < 1e-9      # one plane


def test_one_attempt_is_refused():
    with pytest.raises(ValueError, match="at least two"):
        pose_figures("P3", [0, 0, 0], [[0, 0, 0]])
