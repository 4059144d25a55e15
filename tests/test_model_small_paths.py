"""The forward model's paths for a few poses (a session's twin evaluates one pose at a time) give the floats of the
general code, bit for bit: the chain with fewer numpy calls, the cross products of small arrays, the structural arrays
a model keeps between evaluations.  Exact equality (bytes), not ``allclose``: the demo's recorded data must not move.
"""
from pathlib import Path

import numpy as np
import pytest

from calib import kinematics as kmod
from calib import model as mmod
from calib.angles import rot_zyx
from calib.kinematics import Kinematics, _chain_step, _frame_at
from calib.loading import load_robot

EX = Path(__file__).resolve().parents[1] / "examples"


def _bits(a) -> bytes:
    return np.ascontiguousarray(a, float).tobytes()


def _reference_forward(kin: Kinematics, q: np.ndarray, p: np.ndarray):
    """The pass as written before the few-pose path: each rotation entry on its own, one link step at a time
    (:func:`calib.kinematics._chain_step`).  Returns the frames (R, t) and the tool point."""
    N, n = q.shape[0], kin.n
    lk = p[..., kin._link_cols].T if p.ndim == 2 else p[kin._link_cols].T[:, :, None]
    a, ca, sa, cb, sb = lk[2], np.cos(lk[3]), np.sin(lk[3]), np.cos(lk[4]), np.sin(lk[4])
    base = p[..., :6].T
    R0 = rot_zyx(base[3], base[4], base[5])
    R0 = R0.transpose(1, 2, 0) if p.ndim == 2 else R0[..., None]
    qT = q.T
    theta = lk[0] + qT * kin._revolute[:, None]
    d = lk[1] + qT * kin._prismatic[:, None] if kin._prismatic.any() else lk[1]
    ct, st = np.cos(theta), np.sin(theta)
    A = np.empty((n, 3, 3, N))
    sta, cta = st * sa, ct * sa
    A[:, 0, 0] = cb * ct - sb * sta
    A[:, 1, 0] = cb * st + sb * cta
    A[:, 2, 0] = -sb * ca
    A[:, 0, 1] = -st * ca
    A[:, 1, 1] = ct * ca
    A[:, 2, 1] = sa
    A[:, 0, 2] = sb * ct + cb * sta
    A[:, 1, 2] = sb * st - cb * cta
    A[:, 2, 2] = cb * ca
    off = np.empty((n, 3, N))
    off[:, 0] = a * ct
    off[:, 1] = a * st
    off[:, 2] = d
    R = np.empty((n + 1, 3, 3, N))
    t = np.empty((n + 1, 3, N))
    R[0] = R0
    t[0] = base[:3] if base.ndim == 2 else base[:3, None]
    pf = kin.parent_frame
    for j in range(n):
        _chain_step(R[pf[j]], t[pf[j]], A[j], off[j], R[j + 1], t[j + 1])
    tool = p[..., kin._tool_cols].T
    tool = tool if tool.ndim == 2 else tool[:, None]
    Rn, tn = _frame_at(R, t, kin.tool_frame)
    return R, t, (tn + Rn[:, 0] * tool[0] + Rn[:, 1] * tool[1] + Rn[:, 2] * tool[2]).T


def _robots(puma, tmp_path):
    from tests.fakes import tree_robot as tr
    tree = tr.two_arm_torso(0)
    (tmp_path / "tree.urdf").write_text(tr.to_urdf(tree))
    (tmp_path / "tree.toml").write_text('urdf = "tree.urdf"\nbase_link = "base_link"\n[tool.points]\n'
                                        'L = { link = "hand_left_link", xyz_mm = [0.0, 0.0, 30.0] }\n'
                                        'R = { link = "hand_right_link", xyz_mm = [10.0, 0.0, 30.0] }\n')
    tree_robot = load_robot(tmp_path / "tree.toml")
    assert tree_robot.is_tree
    tiago = load_robot(EX / "tiago" / "tiago_mocap.toml")       # a serial chain with a prismatic joint
    return [puma, tiago, tree_robot]


def test_few_pose_chain_equals_the_link_by_link_pass(puma, tmp_path, rng):
    """Below SMALL_BATCH poses the chain (rotations a few entries at a time, the offsets in one batched product, the
    origins by one accumulate on a serial chain) gives the bytes of the entry-by-entry, link-by-link pass: a serial
    arm, one with a prismatic joint, a tree; one parameter vector (kept terms), one per pose, and one per pose that
    differs in the tool point alone (the first row's kept terms); 1 to 32 poses."""
    for robot in _robots(puma, tmp_path):
        kin = Kinematics(robot)
        for N in (1, 2, 5, kmod.SMALL_BATCH - 1, kmod.SMALL_BATCH):
            q = rng.uniform(-2.5, 2.5, (N, kin.n))
            p = kin.nominal + rng.normal(0, 1e-2, kin.P)
            tools = np.repeat(p[None], N, 0)
            tools[:, kin._tool_cols] += rng.normal(0, 30, (N, 3))     # a tool point per pose: the kept terms
            for params in (p, np.repeat(p[None], N, 0) + rng.normal(0, 1e-3, (N, kin.P)), tools):
                fp = kin.forward(q, params)
                R, t, point = _reference_forward(kin, q, params)
                assert _bits(fp._R) == _bits(R) and _bits(fp._t) == _bits(t), (robot.name, N, params.ndim)
                assert _bits(fp.point) == _bits(point)


def test_small_cross_products_equal_the_componentwise_ones(rng, monkeypatch):
    """:func:`calib.model._cross` on a few vectors (the operands written twice) gives the bytes of the
    component-by-component products, broadcast operands, signed zeros and huge values included."""
    shapes = [((1, 3), (1, 3)), ((1, 6, 3), (1, 1, 3)), ((2, 6, 4, 3), (2, 1, 1, 3)), ((1, 9, 3), (9, 3))]
    for sa, sb in shapes:
        a, b = rng.normal(size=sa), rng.normal(size=sb)
        a.flat[0], b.flat[1] = -0.0, 1e200
        small = mmod._cross(a, b)
        with monkeypatch.context() as m:
            m.setattr(mmod, "SMALL_CROSS", -1)                  # every size component by component
            general = mmod._cross(a, b)
        assert small.shape == general.shape and _bits(small) == _bits(general)


def _reference_compliance(e, q, ctx, loads, values):
    """:meth:`JointCompliance.joint_delta` as written before its first-slope branch: np.where over both slopes."""
    c1, c2, tb, h = values
    j = e.joint - 1
    tau = loads.joint_torque_nm[:, j]
    a, s = np.abs(tau), np.sign(tau)
    below = a <= tb
    tb_f = tb if np.isfinite(tb) else 0.0
    d = np.where(below, c1 * tau, s * (c1 * tb_f + c2 * (a - tb_f))) - 0.5 * h * ctx.load_direction[:, j]
    delta, grad = np.zeros_like(q), np.zeros(q.shape + (4,))
    delta[:, j] = d
    grad[:, j, 0] = np.where(below, tau, s * tb_f)
    grad[:, j, 1] = np.where(below, 0.0, s * (a - tb_f))
    grad[:, j, 2] = np.where(below, 0.0, s * (c1 - c2))
    grad[:, j, 3] = -0.5 * ctx.load_direction[:, j]
    return delta, grad


def test_joint_compliance_first_slope_branch_equals_both_slopes(rng):
    """The joint compliance's branch for poses all below the breakpoint gives the bytes of the two-slope expression:
    no breakpoint, one above every torque, one some torques pass, a NaN torque, signed zeros, dead zone."""
    from calib.effects import Loads, PoseContext
    from calib.effects.joint_compliance import JointCompliance
    for N in (1, 2, 7):
        for breakpoint in (np.inf, 1e6, 20.0):
            e = JointCompliance(3, 2.5e4, 1.1e4, breakpoint, 0.002)
            q = rng.normal(size=(N, 6))
            tau = rng.normal(0, 30, (N, 6))
            tau[0, 2] = -0.0
            for extra in (None, np.nan):
                if extra is not None:
                    tau[-1, 2] = extra
                ctx = PoseContext(N, 6, load_direction=rng.choice([-1.0, 0.0, 1.0], (N, 6)))
                loads = Loads(joint_torque_nm=tau.copy(), tip_force_n=np.zeros((N, 6, 3)))
                got, want = e.joint_delta(q, ctx, loads, e.values), _reference_compliance(e, q, ctx, loads, e.values)
                assert _bits(got[0]) == _bits(want[0]) and _bits(got[1]) == _bits(want[1])


def test_one_model_evaluated_in_turn_equals_fresh_models(puma, rng):
    """What a model keeps between evaluations (the chain's terms per parameter vector, which joint carries which body
    per set of load frames, the frames of its own bodies, a pass's gravity) is never stale: a session's sequence of
    one-pose evaluations -- loads hung on one link then another, none, a payload, targets on the flange and on links,
    two targets together, a geometric parameter and an effect's value moved -- gives, call after call, the bytes a
    fresh model gives (points, true angles, torques, Jacobian)."""
    from calib.effects import CrossCoupling, LinkCompliance, PoseContext, thesis_effects
    from calib.effects.mass_moment import MassMoment
    from calib.model import MeasurementModel
    effects = thesis_effects() + [CrossCoupling(6, 5, 1e-3), LinkCompliance(2, 2e13), MassMoment(3, 1.5, (5.0, 0, 2.0))]
    model = MeasurementModel(puma, effects)
    theta = model.nominal.copy()
    q = rng.uniform(-1.5, 1.5, (1, puma.n))

    def ctx(links=(), payload=0.0, N=1):
        K = len(links)
        return PoseContext(N, puma.n, load_direction=np.ones((N, puma.n)), payload_kg=np.full(N, payload),
                           point_force_link=np.array(links, int), point_force_mm=rng.normal(0, 100, (N, K, 3)),
                           point_force_n=rng.normal(0, 40, (N, K, 3)))

    calls = [dict(ctx=ctx([2]), tool_mm=np.array([10.0, 0.0, 80.0])), dict(ctx=ctx([3, 5]), tool_mm=np.zeros(3)),
             dict(ctx=ctx(), tool_mm=np.array([10.0, 0.0, 80.0])), dict(ctx=ctx(payload=2.0)),
             dict(ctx=ctx([2]), tool_mm=np.array([300.0, 5.0, 0.0]), link=2), dict(ctx=ctx(), tool_mm=np.ones(3), link=4),
             dict(ctx=ctx([2], N=2), tool_mm=rng.normal(0, 50, (2, 3)), q=np.repeat(q, 2, 0))]
    for step in range(3):
        for kw in calls:
            qq = kw.pop("q", q)
            got = model.evaluate(qq, theta=theta, jacobian=True, **kw)
            want = MeasurementModel(puma, effects).evaluate(qq, theta=theta.copy(), jacobian=True, **kw)
            for attr in ("point_mm", "theta_rad", "jacobian"):
                assert _bits(getattr(got, attr)) == _bits(getattr(want, attr)), (step, attr, kw)
            assert _bits(got.loads.joint_torque_nm) == _bits(want.loads.joint_torque_nm)
            kw["q"] = qq
        theta[model.index["j2.a_mm"]] += 0.5 if step == 0 else 0.0           # the geometry moved
        theta[model.names.index(next(n for n in model.names if n.startswith("mass_moment")))] += 0.3 * step


def test_a_context_copies_arrays_of_its_own_shape(rng):
    """A pose context built from arrays of the shape it keeps holds copies equal to the broadcast ones (the twin
    builds one every state): writing to the caller's array afterwards changes nothing."""
    from calib.effects import PoseContext
    d, f = rng.normal(size=(2, 6)), rng.normal(size=(2, 1, 3))
    ctx = PoseContext(2, 6, direction=d, point_force_link=[3], point_force_n=f, payload_kg=1.5)
    assert _bits(ctx.direction) == _bits(d) and _bits(ctx.point_force_n) == _bits(f)
    assert _bits(ctx.payload_kg) == _bits(np.full(2, 1.5))
    d[:] = 0.0
    f[:] = 0.0
    assert ctx.direction.any() and ctx.point_force_n.any()


def test_few_pose_cross_into_equals_the_componentwise_one(rng, monkeypatch):
    """:func:`calib.kinematics._cross_into` for a few poses (operands written twice) writes the bytes of the
    component-by-component products: broadcast operands as the element Jacobian passes them, signed zeros."""
    cases = [((3, 1), (3, 4), (3, 4)), ((6, 3, 2), (6, 3, 2), (6, 3, 2)), ((3, 5), (6, 3, 5), (6, 3, 5))]
    for sa, sb, so in cases:
        a, b = rng.normal(size=sa), rng.normal(size=sb)
        a.flat[1] = -0.0
        small, general = np.empty(so), np.empty(so)
        kmod._cross_into(small, a, b)
        with monkeypatch.context() as m:
            m.setattr(kmod, "SMALL_BATCH", 0)                 # every batch component by component
            kmod._cross_into(general, a, b)
        assert _bits(small) == _bits(general)
