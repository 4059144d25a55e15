"""The loads of a loading series computed together (:func:`offline.reduction.torques.series_loads`): each step's
torques, axes and error terms are its own -- the same as the step alone -- and the hung masses' torque is the lever
arm crossed with the weight, by plain vector algebra on the chain's frames."""
from types import SimpleNamespace

import numpy as np

from calib.loading import load_robot
from calib.model import MeasurementModel
from offline.reduction.torques import series_loads, step_loads


def _step(pose_deg, loads):
    return {"spec": {"pose_deg": list(pose_deg), "setup": {"loads": loads}}}


def _series(rng, robot):
    steps = []
    for k in range(9):
        pose = rng.uniform(-60, 60, robot.n)
        if k % 3 == 2:          # a different set of links, and a step with nothing hung
            loads = [] if k == 8 else [{"link": 3, "point_mm": [10.0, 0.0, 250.0], "mass_kg": 1.5},
                                       {"link": 6, "point_mm": [0.0, 0.0, 80.0], "mass_kg": 0.5 * k}]
        else:
            loads = [{"link": 6, "point_mm": [0.0, 30.0, 120.0], "mass_kg": 0.25 * (k + 1)}]
        steps.append(_step(pose, loads))
    return steps


def test_a_series_gives_each_step_its_own_loads():
    rng = np.random.default_rng(3)
    robot = load_robot()
    model = MeasurementModel(robot)
    theta = model.nominal
    ctx = SimpleNamespace(robot=robot)
    steps = _series(rng, robot)
    for errors in (True, False):
        together = series_loads(steps, ctx, model, theta, errors)
        for s, got in zip(steps, together):
            alone = step_loads(s, ctx, model, theta, errors)
            for name in ("q_rad", "torque_nm", "axes", "dtau_dgeo", "dtau_dpoint", "hung_nm_per_kg"):
                a, b = getattr(got, name), getattr(alone, name)
                if b is None:
                    assert a is None
                else:
                    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12, err_msg=name)


def test_hung_torque_is_the_lever_times_the_weight():
    """Joint i turns under a mass hung on link j >= i by ((p - o_i) x m g) . z_i per kg: the point and the joint's
    axis from the chain's frames, gravity from the model's; summed by hand, not through the model's loads."""
    rng = np.random.default_rng(4)
    robot = load_robot()
    model = MeasurementModel(robot)
    theta = model.nominal
    steps = [s for s in _series(rng, robot) if len(s["spec"]["setup"]["loads"]) == 1]
    g = model.gravity_n_per_kg(theta)
    for s, got in zip(steps, series_loads(steps, SimpleNamespace(robot=robot), model, theta)):
        ld = s["spec"]["setup"]["loads"][0]
        fp = model.kin.forward(np.radians(s["spec"]["pose_deg"])[None], theta[: model.n_geometric])
        p = fp.frame_t[0, ld["link"]] + fp.frame_R[0, ld["link"]] @ np.array(ld["point_mm"])
        want = [np.dot(np.cross((p - fp.joint_origin[0, i]) * 1e-3, g), fp.joint_axis[0, i]) if i < ld["link"]
                else 0.0 for i in range(robot.n)]
        np.testing.assert_allclose(got.hung_nm_per_kg, want, rtol=1e-9, atol=1e-9)
