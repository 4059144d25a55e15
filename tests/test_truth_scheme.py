"""The emulated truths of the misalignment table and the compensation scheme (eqs 4.3.10-15) against the oracle's
own copy of the thesis's formulas (tests/fakes/oracle/scheme.py) on axes of the independent chain
(tests/fakes/thesis_puma.py) -- never against calib.estimators, whose output these truths judge."""
from __future__ import annotations

from importlib import resources

import numpy as np
import pytest

from acq.session.procedures import sweep_target
from acq.session.setup import point_p
from sim.emulate.truth.scheme import misalignment_rows, puma_lengths
from tests.fakes.oracle import scheme as oracle
from tests.fakes.thesis_puma import DEG, ThesisPuma

PUMA_TOML = resources.files("calib") / "data" / "puma560.toml"
READY = np.array([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]) * DEG
BASE = {"base.x_mm": 474.9, "base.y_mm": 2853.0, "base.z_mm": 184.9, "base.yaw_rad": 0.02}
DRAWN = {"j2.a_mm": 431.0, "j3.a_mm": -29.7, "j2.d_mm": 154.5, "j4.d_mm": 432.2, "j6.d_mm": 56.4}
ROW = ("dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "delta_alpha_rad", "delta_beta_rad", "delta_theta_rad")
#: where each joint's target sits on its link (frame j), mm: off the axis, as a sweep's target is
TARGETS = [(1, (300.0, 0.0, 50.0)), (2, (-200.0, 0.0, 120.0)), (3, (0.0, 150.0, 80.0)), (4, (0.0, 120.0, 0.0)),
           (5, (0.0, 0.0, 160.0)), (6, (50.0, 0.0, 100.0))]
L_P = 150.0


def arm_axes(arm: ThesisPuma, q, targets=TARGETS, p_link: int = 6, L_p: float = L_P):
    """Each joint's axis as a sweep measures it -- the foot of its target on the axis, the direction -- and point P
    ``L_p`` along frame ``p_link``'s z, all from the independent chain's frames at the joint angles ``q``."""
    F = arm.frames(q)
    axes = []
    for j, (link, point) in enumerate(targets):
        o, z = F[j][:3, 3], F[j][:3, 2]
        x = F[link][:3, :3] @ np.asarray(point, float) + F[link][:3, 3]
        axes.append((o + ((x - o) @ z) * z, z))
    return axes, F[p_link][:3, :3] @ np.array([0.0, 0.0, L_p]) + F[p_link][:3, 3]


def design_frames(design: ThesisPuma, q):
    """Design axis directions and common normals (x of the next frame) at the readings ``q``."""
    F = design.frames(q)
    return [F[j][:3, 2] for j in range(6)], [F[j + 1][:3, 0] for j in range(6)]


def misaligned(seed: int) -> dict[str, float]:
    """Fig 5.10's lengths with seeded twists, zero offsets and a Hayati beta, under robocal's names."""
    rng = np.random.default_rng(seed)
    p = dict(BASE, **DRAWN)
    for j in range(6):
        p[f"j{j + 1}.alpha_rad"] = ThesisPuma().alpha[j] + rng.normal(0.0, 0.15 * DEG)
        p[f"j{j + 1}.theta_offset_rad"] = rng.normal(0.0, 0.10 * DEG)
    p["j2.beta_rad"] = rng.normal(0.0, 0.05 * DEG)
    return p


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_truths_formulas_are_the_oracles(seed):
    """The sim side's eqs 4.3.10-15 (what the demo prints as truth) on a misaligned arm of the independent chain:
    equal to the oracle's to rounding."""
    design = ThesisPuma.from_toml(PUMA_TOML).with_parameters(BASE)
    arm = design.with_parameters(misaligned(seed))
    axes, P = arm_axes(arm, READY)
    zd, xd = design_frames(design, READY)
    table = oracle.misalignment_table(zd, [n for _, n in axes], xd)
    rows = misalignment_rows(np.array([n for _, n in axes]), np.array(zd), np.array(xd))
    np.testing.assert_allclose(rows, [[r[k] for k in ROW] for r in table], rtol=0, atol=1e-12)
    assert np.abs(rows).max() > 1e-3                                # misaligned by milliradians: not a zero test
    base_R = design.base[:3, :3]
    want = oracle.eq_4_3_15(axes, zd, xd, P, L_P, base_R)
    got = puma_lengths(np.array([np.r_[c, n] for c, n in axes]), np.array(zd), np.array(xd), P, L_P, base_R)
    assert got == pytest.approx(want, abs=1e-9)


def test_the_oracles_scheme_reads_a_drawn_puma():
    """The oracle anchored to geometry: an arm without misalignment at READY gives the drawn lengths (a2 along the
    base's x, the opposite sign of Fig 5.10's; d2 the elbow-wrist distance); a twist of link 1 tilts axis 2 and moves
    the wrist sideways by about 864 mm x the twist, which eq 4.3.15's d1 reads as shoulder offset -- why the
    emulated truth of d1 is the scheme's reading of the twin's axes, with the twin's own d as truth_raw."""
    design = ThesisPuma.from_toml(PUMA_TOML).with_parameters(BASE)
    arm = design.with_parameters(DRAWN)
    zd, xd = design_frames(design, READY)
    axes, P = arm_axes(arm, READY)
    got = oracle.eq_4_3_15(axes, zd, xd, P, L_P, design.base[:3, :3])
    assert got == pytest.approx({"a1_mm": 431.0, "a2_mm": 29.7, "d1_mm": 154.5, "d2_mm": np.hypot(432.2, 29.7),
                                 "d3_mm": 56.4}, abs=1e-9)
    twist = 0.15 * DEG
    tilted = arm.with_parameters({"j1.alpha_rad": arm.alpha[0] + twist})
    axes, P = arm_axes(tilted, READY)
    moved = oracle.eq_4_3_15(axes, zd, xd, P, L_P, design.base[:3, :3])
    assert abs(abs(moved["d1_mm"] - 154.5) - 863.2 * twist) < 0.05 * 863.2 * twist, moved
    assert moved["a1_mm"] == pytest.approx(431.0, abs=0.01)


def test_the_misalignment_of_a_turned_axis_is_its_angle():
    """Eq 4.3.10 in the oracle: an axis turned by 0.5 deg about x reads (0.5 deg, 0, 0)."""
    a = 0.5 * DEG
    got = oracle.axis_misalignment([0.0, 0.0, 1.0], [0.0, -np.sin(a), np.cos(a)])
    assert got == pytest.approx([a, 0.0, 0.0], abs=1e-15)


def session_truths(twin, setup, q0) -> dict[str, float]:
    """The oracle's truths of a session's misalignment table and compensation scheme: the twin's true parameters
    (data, under robocal's names) on the independent chain at the twin's effective joint angles at the reference
    pose ``q0``, the design chain at the readings, the sweep targets and point P where the set-up puts them."""
    design = ThesisPuma.from_toml(PUMA_TOML).with_parameters(
        {"base.x_mm": setup.base_xyz_mm[0], "base.y_mm": setup.base_xyz_mm[1], "base.z_mm": setup.base_xyz_mm[2],
         "base.roll_rad": setup.base_rpy_deg[0] * DEG, "base.pitch_rad": setup.base_rpy_deg[1] * DEG,
         "base.yaw_rad": setup.base_rpy_deg[2] * DEG})
    arm = design.with_parameters(twin.true_parameters())
    _, theta = twin.true_points(np.asarray(q0, float)[None])
    targets = [(6 if t.link is None else t.link, t.tool_mm) for t in (sweep_target(setup, j) for j in range(1, 7))]
    link, _, L_p = point_p(setup)
    axes, P = arm_axes(arm, theta[0], targets, link, L_p)
    zd, xd = design_frames(design, q0)
    out = {f"misalign.j{j + 1}.{k}": v for j, r in enumerate(oracle.misalignment_table(zd, [n for _, n in axes], xd))
           for k, v in r.items()}
    out.update({f"comp.{k}": v for k, v in oracle.eq_4_3_15(axes, zd, xd, P, L_p, design.base[:3, :3]).items()})
    out["comp.d3_mm"] = twin.true_parameters()["j6.d_mm"]       # d3: the twin's flange offset itself
    return out
