"""Gravity-loaded backlash (issue 27, item 2) against the independent generator of tests/fakes/backlash_sessions.py:
its own 4x4 chain, its own gravity torque with a lumped tool mass, its own play."""
from __future__ import annotations

import numpy as np
import pytest

from calib.effects import PoseContext, effect_from_spec, effect_from_text, effect_spec, make_effect
from calib.model import MeasurementModel
from calib.loading import load_robot
from calib.units import DEG

from .fakes.backlash_sessions import Arm, Play, approach_of, program
from .fakes.thesis_puma import base_matrix

BASE = ((1500.0, -300.0, -400.0), 0.3, 0.02, -0.01)
TOOL_MM = (0.0, 0.0, 120.0)          # the generator's ^6E (0, 0, -120): the tool 120 mm out along z6


def _model(effects):
    m = MeasurementModel(load_robot(), effects)
    th = m.nominal.copy()
    for k, v in zip(("x_mm", "y_mm", "z_mm"), BASE[0]):
        th[m.index[f"base.{k}"]] = v
    for k, v in zip(("yaw_rad", "pitch_rad", "roll_rad"), BASE[1:]):
        th[m.index[f"base.{k}"]] = v
    for k, v in zip(("x_mm", "y_mm", "z_mm"), TOOL_MM):
        th[m.index[f"tool.{k}"]] = v
    return m, th


def _arm(plays, tool_mass_kg):
    arm = Arm(plays, tool_mass_kg=tool_mass_kg)
    arm.puma.base = base_matrix(*BASE)
    return arm


def test_the_models_torque_with_a_tool_mass_is_the_generators():
    q = program(25, seed=1)
    arm = _arm([], 2.5)
    m, th = _model([make_effect("backlash_gravity", 5)])
    ev = m.evaluate(q, theta=th)
    tau = ev.loads.joint_torque_nm + 2.5 * ev.loads.tool_torque_per_kg
    np.testing.assert_allclose(tau, [arm.torques(qi) for qi in q], atol=1e-9)
    assert np.ptp(ev.loads.tool_torque_per_kg[:, 4]) > 0.5          # the tool mass matters about joint 5


@pytest.mark.parametrize("joint, preload, mass", [(5, 1.0, 2.0), (2, 30.0, 0.0), (3, 0.0, 1.0), (3, np.inf, 0.0)])
def test_points_are_the_generators(joint, preload, mass):
    """Each pose rests where its torque pushes it above the preload, where its last move left it below: the model's
    points equal the generator's to 1e-8 mm (an infinite preload is the plain backlash)."""
    q = program(40, seed=joint)
    appr = approach_of(q, q[0] * 0.0)
    width = 0.3 * DEG
    arm = _arm([Play(joint, width, preload)], mass)
    e = make_effect("backlash_gravity", joint, preload_nm=min(preload, 1e9), tool_mass_kg=mass)
    e.values[:] = width
    m, th = _model([e])
    got = m.points(q, PoseContext(len(q), 6, direction=appr), th)
    want = np.array([arm.puma.tool_point(arm.true_angles(qi, a)) for qi, a in zip(q, appr)])
    np.testing.assert_allclose(got, want, atol=1e-8)
    held = np.abs([arm.torques(qi)[joint - 1] for qi in q]) > preload
    if 0 < held.mean() < 1:           # both kinds of pose occur: the test can tell gravity from approach
        plain = make_effect("backlash", joint)
        plain.values[:] = width
        mp, thp = _model([plain])
        assert np.abs(mp.points(q, PoseContext(len(q), 6, direction=appr), thp) - want).max() > 0.05


def test_the_width_column_is_half_the_side_and_the_kind_round_trips():
    e = effect_from_text("backlash_gravity:5:0.7:1.5")
    assert (e.joint, e.preload_nm, e.tool_mass_kg) == (5, 0.7, 1.5)
    assert "preload 0.7 N m" in e.finding_label() and "tool mass 1.5 kg" in e.finding_label()
    back = effect_from_spec(effect_spec(e), {"backlash_gravity.j5.width_rad": 0.01}, "x")
    assert (back.preload_nm, back.tool_mass_kg, back.values[0]) == (0.7, 1.5, 0.01)
    q = program(10, seed=2)
    m, th = _model([e])
    ev = m.evaluate(q, PoseContext(10, 6, direction=approach_of(q, q[0])), th, jacobian=True)
    col = ev.jacobian[:, :, m.effect_slices[0].start]
    np.testing.assert_allclose(np.einsum("nij,nj->ni", ev.joint_jacobian, 0.5 * e.side(
        PoseContext(10, 6, direction=approach_of(q, q[0])), ev.loads)[:, None] * np.eye(6)[4]), col, atol=1e-9)
    with pytest.raises(ValueError):
        make_effect("backlash_gravity", 2, preload_nm=-1.0)
