"""Forces at points on links (contract C2): the model's joint torques, link tip forces, points fixed on links and
their Jacobians, against plain 4x4 products and cross products (tests/fakes/point_loads.py)."""
from __future__ import annotations

import numpy as np
import pytest

from calib.effects import JointCompliance, PoseContext
from calib.model import MeasurementModel
from calib.units import DEG
from tests.fakes.oracle.chain import numeric_jacobian
from tests.fakes.point_loads import point_force_torques, point_in_frame

READY = np.array([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]) * DEG


def _poses(rng, robot, k=5):
    lim = robot.limits_rad
    return lim[:, 0] + (lim[:, 1] - lim[:, 0]) * rng.random((k, robot.n))


def _ctx(model, N, links, pts, forces):
    return model.context(N, point_force_link=np.asarray(links), point_force_mm=pts, point_force_n=forces)


def test_point_forces_give_the_cross_product_torques(puma, rng):
    m = MeasurementModel(puma)
    q = _poses(rng, puma)
    links = np.array([0, 1, 2, 3, 4, 5, 6, 3])
    pts = rng.normal(0, 300, (len(q), len(links), 3))
    F = rng.normal(0, 50, (len(q), len(links), 3))
    base = m.loads(m.kin.forward(q), m.context(len(q)))
    got = m.loads(m.kin.forward(q), _ctx(m, len(q), links, pts, F))
    for i in range(len(q)):
        want = sum(point_force_torques(puma, q[i], int(b), pts[i, k], F[i, k]) for k, b in enumerate(links))
        np.testing.assert_allclose(got.joint_torque_nm[i] - base.joint_torque_nm[i], want, atol=1e-9)
        # the end of link j carries the forces fixed beyond frame j
        for j in range(1, puma.n + 1):
            want_tip = F[i, links > j].sum(0)
            np.testing.assert_allclose(got.tip_force_n[i, j - 1] - base.tip_force_n[i, j - 1], want_tip, atol=1e-9)


def test_a_weight_on_a_vertical_axis_turns_nothing(puma):
    """At READY joints 1 and 4 are vertical: a hung mass on link 4 loads joints 2 and 3 only."""
    m = MeasurementModel(puma)
    g = m.gravity_n_per_kg()
    ctx = _ctx(m, 1, [4], [[[0.0, 0.0, 300.0]]], [[10.0 * g]])
    d = (m.loads(m.kin.forward(READY[None]), ctx).joint_torque_nm
         - m.loads(m.kin.forward(READY[None]), m.context(1)).joint_torque_nm)[0]
    assert abs(d[0]) < 1e-9 and abs(d[3]) < 1e-9 and abs(d[4]) < 1e-9 and abs(d[5]) < 1e-9
    assert abs(d[1]) > 1.0 and abs(d[2]) > 1.0


def test_hung_mass_deflects_its_joint_by_torque_over_stiffness(puma):
    """Joint 4 horizontal (forearm level), the mass on a lever across it: the joint gives way by tau / K."""
    k = 25704.0
    m = MeasurementModel(puma, [JointCompliance(4, k)])
    q = np.array([[0.0, -90.0, 0.0, 0.0, 0.0, 0.0]]) * DEG
    g = m.gravity_n_per_kg()
    p = [0.0, 0.0, -400.0]                      # along joint 5's axis: level and across joint 4
    ctx = _ctx(m, 1, [4], [[p]], [[5.0 * g]])
    dth = m.evaluate(q, ctx).theta_rad - m.evaluate(q).theta_rad
    tau = point_force_torques(puma, q[0], 4, p, 5.0 * g)
    assert abs(tau[3]) > 5.0
    np.testing.assert_allclose(dth[0, 3], tau[3] / k, rtol=1e-9)
    np.testing.assert_allclose(np.delete(dth[0], 3), 0.0, atol=1e-15)


@pytest.mark.parametrize("link", [0, 2, 4, 6])
def test_points_fixed_on_a_link(puma, rng, link):
    m = MeasurementModel(puma)
    q = _poses(rng, puma, 4)
    p = np.array([120.0, -40.0, 75.0])
    ev = m.evaluate(q, tool_mm=p, link=link, jacobian=True)
    for i in range(len(q)):
        np.testing.assert_allclose(ev.point_mm[i], point_in_frame(puma, q[i], link, p), atol=1e-9)
    # joints beyond the link do not move the point
    q2 = q.copy()
    q2[:, link:] += 0.3
    np.testing.assert_allclose(m.points(q2, tool_mm=p, link=link), ev.point_mm, atol=1e-9)
    # the Jacobian against central differences of the parameters and the point's own coordinates
    num_th = numeric_jacobian(lambda th: m.points(q, theta=th, tool_mm=p, link=link), m.nominal, 1e-6)
    num_p = numeric_jacobian(lambda pp: m.points(q, tool_mm=pp, link=link), np.asarray(p, float), 1e-6)
    for i in range(m.n_geometric):                 # a tool column moves the point given, not the model's tool
        num = num_p[:, :, "xyz".index(m.names[i][5])] if m.names[i].startswith("tool.") else num_th[:, :, i]
        np.testing.assert_allclose(ev.jacobian[:, :, i], num, atol=1e-5, err_msg=m.names[i])
    num_q = numeric_jacobian(lambda qq: m.points(qq, tool_mm=p, link=link), q, 1e-6)   # each pose its own row
    np.testing.assert_allclose(ev.joint_jacobian, num_q, atol=1e-5)


def test_torque_derivative_with_point_forces(puma, rng):
    m = MeasurementModel(puma)
    q = _poses(rng, puma, 3)
    links = [2, 4, 6]
    pts = rng.normal(0, 200, (len(q), 3, 3))
    F = rng.normal(0, 40, (len(q), 3, 3))
    ctx = _ctx(m, len(q), links, pts, F)
    geo = m.nominal[: m.n_geometric]
    d = m.loads(m.kin.forward(q, geo), ctx, derivative=True).dtau_dgeo
    num_all = numeric_jacobian(lambda g: m.loads(m.kin.forward(q, g), ctx).joint_torque_nm, geo, 1e-6)
    for i, name in enumerate(m.kin.names):
        if name.startswith("base."):
            continue                    # gravity is given in frame 0: the model lets the base carry it along
        num = num_all[:, :, i]
        np.testing.assert_allclose(d[:, :, i], num, atol=1e-6 * max(1.0, np.abs(num).max()), err_msg=name)


def test_context_refuses_a_frame_that_does_not_exist():
    with pytest.raises(ValueError):
        PoseContext(1, 6, point_force_link=[7])
    c = PoseContext(3, 6, point_force_link=[1, 2])
    assert c.point_force_mm.shape == (3, 2, 3) and c.subset([0, 2]).point_force_n.shape == (2, 2, 3)


def test_link_bending_under_a_mass_on_the_link(puma):
    """Link compliance of link 2 with a mass on link 2 at a: a point on link 2 at x moves by the cantilever
    deflection P x^2 (3a - x) / (6 EI) across the link; a point on link 1 does not move."""
    from calib.effects import LinkCompliance
    from tests.fakes.oracle.beam import cantilever_deflection
    from tests.fakes.point_loads import frames
    ei = 2.0e11
    m = MeasurementModel(puma, [LinkCompliance(2, ei)])
    q = np.array([0.0, -20.0, 60.0, 0.0, 0.0, 0.0]) * DEG
    T = frames(puma, q)
    o1, o2, R2 = T[1][:3, 3], T[2][:3, 3], T[2][:3, :3]
    z1 = T[1][:3, 2]
    o1 = o1 + ((o2 - o1) @ z1) * z1                                      # the link leaves joint 2's axis here
    L = np.linalg.norm(o2 - o1)
    u = (o2 - o1) / L
    on_link = lambda x: R2.T @ (o1 + u * x - o2)                         # noqa: E731 frame-2 coordinates
    g = m.gravity_n_per_kg()
    a, mass = 300.0, 20.0
    ctx = _ctx(m, 1, [2], [[on_link(a)]], [[mass * g]])
    P = mass * g - (mass * g @ u) * u                                    # the force across the link
    for x in (100.0, 250.0, 400.0):
        d = m.points(q[None], ctx, tool_mm=on_link(x), link=2) - m.points(q[None], tool_mm=on_link(x), link=2)
        # the oracle integrates EI y'' = M (not the closed form the model uses): equal to its grid's 1e-9
        want = cantilever_deflection(x, a, 1.0, ei) * P
        np.testing.assert_allclose(d[0], want, rtol=1e-8, atol=1e-12)
    d1 = m.points(q[None], ctx, tool_mm=[10.0, 20.0, 30.0], link=1) - m.points(q[None], tool_mm=[10.0, 20.0, 30.0],
                                                                              link=1)
    assert np.all(d1 == 0.0)
