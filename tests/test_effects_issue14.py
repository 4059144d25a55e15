"""The effects issue 14 adds (joint_scale, axis_tilt, parallel_axes, instrument_drift, tool_flex) against the
independent generator (tests/fakes/issue14_effects.py on the thesis's own chain), and how they are built."""
from importlib import resources

import numpy as np
import pytest

from calib.effects import EFFECTS, effect_from_text, make_effect
from calib.errors import RobocalError
from calib.model import MeasurementModel
from calib.loading import load_robot
from calib.units import DEG
from tests.fakes import issue14_effects as fake
from tests.fakes.oracle.chain import numeric_jacobian
from tests.fakes.thesis_puma import ThesisPuma, base_matrix

PUMA_TOML = resources.files("calib") / "data" / "puma560.toml"
BASE = dict(xyz=(474.9, 2853.0, 184.9), yaw=0.4, pitch=0.002, roll=-0.003)
TOOL_MM = (50.0, 20.0, 100.0)


def setup(effect, seed=0, n=12):
    rng = np.random.default_rng(seed)
    arm = ThesisPuma.from_toml(PUMA_TOML)
    arm.base = base_matrix(BASE["xyz"], BASE["yaw"], BASE["pitch"], BASE["roll"])
    arm.tool_xyz_t = tuple(-v for v in TOOL_MM)
    robot = load_robot()
    m = MeasurementModel(robot, [effect])
    th = m.nominal.copy()
    for k, v in zip(("x_mm", "y_mm", "z_mm"), BASE["xyz"]):
        th[m.index[f"base.{k}"]] = v
    for k in ("yaw", "pitch", "roll"):
        th[m.index[f"base.{k}_rad"]] = BASE[k]
    for k, v in zip(("x_mm", "y_mm", "z_mm"), TOOL_MM):
        th[m.index[f"tool.{k}"]] = v
    th[m.effect_slices[0]] = effect.values
    q = rng.uniform(-1.5, 1.5, (n, 6))
    return arm, m, th, q


def test_the_plain_chains_agree_before_any_effect():
    arm, m, th, q = setup(make_effect("joint_scale", 2))
    np.testing.assert_allclose(m.points(q, theta=th), [arm.tool_point(qi) for qi in q], atol=1e-8)


def test_joint_scale():
    e = effect_from_text("joint_scale:3")
    e.values[:] = 2e-3
    arm, m, th, q = setup(e)
    np.testing.assert_allclose(m.points(q, theta=th), [fake.joint_scale_point(arm, qi, 3, 2e-3) for qi in q],
                               atol=1e-8)


def test_axis_tilt():
    e = make_effect("axis_tilt", 2)
    e.values[:] = [0.01 * DEG, -0.02 * DEG]
    arm, m, th, q = setup(e)
    want = [fake.axis_tilt_point(arm, qi, 2, 0.01 * DEG, -0.02 * DEG) for qi in q]
    # the model is linear in the tilt: second order is (4e-4 rad)^2 x 1 m ~ 1e-4 mm
    np.testing.assert_allclose(m.points(q, theta=th), want, atol=2e-4)
    assert np.abs(np.asarray(want) - m.points(q, theta=np.where(np.isin(np.arange(m.P), range(
        m.effect_slices[0].start, m.effect_slices[0].stop)), 0.0, th))).max() > 0.1


def test_parallel_axes_is_hayatis_beta():
    e = make_effect("parallel_axes", 2)
    e.values[:] = 0.03 * DEG
    arm, m, th, q = setup(e)
    np.testing.assert_allclose(m.points(q, theta=th), [fake.parallel_axes_point(arm, qi, 2, 0.03 * DEG) for qi in q],
                               atol=2e-4)


@pytest.mark.parametrize("step_s", [0.0, 1800.0])
def test_instrument_drift_step_and_ramp(step_s):
    e = make_effect("instrument_drift", step_s=step_s, reference_s=600.0)
    v = np.array([0.3, -0.2, 0.1])
    e.values[:] = v
    arm, m, th, q = setup(e)
    t = np.linspace(0, 3600, len(q))
    pts = m.points(q, m.context(len(q), time_s=t), th)
    u = (t >= step_s).astype(float) if step_s else (t - 600.0) / 3600.0
    np.testing.assert_allclose(pts, [fake.drift_point(arm, qi, v * ui) for qi, ui in zip(q, u)], atol=1e-8)


def test_tool_flex():
    e = make_effect("tool_flex")
    e.values[:] = 0.25
    arm, m, th, q = setup(e)
    np.testing.assert_allclose(m.points(q, theta=th), [fake.tool_flex_point(arm, qi, 0.25) for qi in q], atol=1e-8)


def test_tool_flex_sags_along_the_descriptions_gravity_on_a_wall():
    """A wall-mounted Puma: its base turned 90 deg about y in the measurement frame, its description's gravity along
    -x of frame 0 (down in the room).  The sag follows the room's down, computed here in plain numpy from the thesis
    chain's frames, not -z of the base (which is horizontal on the wall); loads and tool flex share the gravity."""
    from dataclasses import replace
    g_desc = np.array([-9.80665, 0.0, 0.0])
    base = dict(BASE, pitch=-np.pi / 2)
    arm = ThesisPuma.from_toml(PUMA_TOML)
    arm.base = base_matrix(base["xyz"], base["yaw"], base["pitch"], base["roll"])
    arm.tool_xyz_t = tuple(-v for v in TOOL_MM)
    e = make_effect("tool_flex")
    m = MeasurementModel(replace(load_robot(), gravity_m_s2=g_desc), [e])
    th = m.nominal.copy()
    for k, v in [*zip(("x_mm", "y_mm", "z_mm"), base["xyz"]), *zip(("yaw_rad", "pitch_rad", "roll_rad"),
                                                                   (base["yaw"], base["pitch"], base["roll"]))]:
        th[m.index[f"base.{k}"]] = v
    for k, v in zip(("x_mm", "y_mm", "z_mm"), TOOL_MM):
        th[m.index[f"tool.{k}"]] = v
    th[m.effect_slices[0]] = 0.25
    q = np.random.default_rng(4).uniform(-1.5, 1.5, (12, 6))
    down = arm.base[:3, :3] @ g_desc / 9.80665
    np.testing.assert_allclose(down, [0.0, 0.0, -1.0], atol=1e-12)       # the wall mount: down is the room's -z
    want = []
    for qi in q:
        z = arm.frames(qi)[6][:3, 2]
        want.append(arm.tool_point(qi) + 0.25 * (down - (down @ z) * z))
    np.testing.assert_allclose(m.points(q, theta=th), want, atol=1e-8)
    np.testing.assert_allclose(m.gravity_n_per_kg(th), 9.80665 * down, atol=1e-9)


@pytest.mark.parametrize("kind", ["joint_scale", "axis_tilt", "parallel_axes", "instrument_drift", "tool_flex"])
def test_jacobian_of_the_new_effects_matches_finite_differences(kind):
    e = make_effect(kind, 3) if EFFECTS[kind].has_joint else make_effect(kind)
    e.values[:] = 1e-4
    arm, m, th, q = setup(e)
    ctx = m.context(len(q), time_s=np.linspace(0, 7200, len(q)))
    J = m.evaluate(q, ctx, th, jacobian=True).jacobian
    s = m.effect_slices[0]

    def points(values):
        t = th.copy()
        t[s] = values
        return m.points(q, ctx, t)
    fd_all = numeric_jacobian(points, th[s], 1e-6)
    for k in range(s.start, s.stop):
        fd = fd_all[:, :, k - s.start]
        np.testing.assert_allclose(J[:, :, k], fd, atol=1e-5 * max(1.0, np.abs(fd).max()))


def test_the_new_kinds_are_built_through_the_registry():
    assert {"joint_scale", "axis_tilt", "parallel_axes", "instrument_drift", "tool_flex"} <= set(EFFECTS)
    assert effect_from_text("instrument_drift:900").step_s == 900.0
    with pytest.raises(RobocalError, match="joint must be 1..6"):
        effect_from_text("axis_tilt:9")
