"""Each non-geometric effect shows its own signature, and its Jacobian matches finite differences."""
import json
from importlib import resources

import numpy as np
import pytest

from calib.effects import (Backlash, CrossCoupling, JointCompliance, LinkCompliance, ThermalDrift,
                           TransmissionError, thesis_effects)
from calib.model import TORQUE_TERM_THRESHOLD, MeasurementModel, torque_term_size
from calib.units import DEG, G0_M_S2, NM_PER_LBIN
from tests.fakes import thesis_puma as fake
from tests.fakes.oracle.chain import numeric_jacobian, point_in
from tests.fakes.point_loads import frames
from tests.fakes.thesis_puma import ThesisPuma


def poses(rng, n=40):
    return rng.uniform(-1.2, 1.2, (n, 6))


def test_transmission_error_is_periodic_in_its_joint_only(puma, rng):
    m = MeasurementModel(puma, [TransmissionError(4, 0.9, [0.050 * DEG], [])])
    q = poses(rng)
    d = m.evaluate(q).theta_rad - q
    np.testing.assert_allclose(d[:, 3], 0.050 * DEG * np.sin(0.9 * q[:, 3]), atol=1e-15)
    assert np.all(d[:, [0, 1, 2, 4, 5]] == 0)
    shifted = q.copy()
    shifted[:, 3] += 2 * np.pi / 0.9                       # one period later
    shifted[:, 0] += 0.7                                   # other joints do not matter
    np.testing.assert_allclose(m.evaluate(shifted).theta_rad[:, 3] - shifted[:, 3], d[:, 3], atol=1e-12)


def test_backlash_flips_with_approach_direction(puma, rng):
    b = 0.02 * DEG
    m = MeasurementModel(puma, [Backlash(2, b)])
    q = poses(rng)
    up = m.evaluate(q, m.context(len(q), direction=np.ones((len(q), 6))))
    down = m.evaluate(q, m.context(len(q), direction=-np.ones((len(q), 6))))
    np.testing.assert_allclose(down.theta_rad[:, 1] - up.theta_rad[:, 1], b, atol=1e-15)
    gap = np.linalg.norm(down.point_mm - up.point_mm, axis=1)
    assert np.all(gap > 0.05)                               # 0.02 deg at > 150 mm reach


def gravity_torque_by_virtual_work(model, q, h=1e-6):
    """tau_j = -dU/dq_j with U the potential energy of the link masses, the links placed by the oracle's plain
    products (independent of Model.loads and of calib.kinematics)."""
    r = model.robot
    g = r.gravity_m_s2

    def U(qq):
        out = []
        for row in qq:
            T = frames(r, row)
            com = np.array([point_in(T[k + 1], r.com_mm[k]) for k in range(r.n)])
            out.append(-np.einsum("kc,c,k->", com * 1e-3, g, r.mass_kg))
        return np.array(out)

    return -numeric_jacobian(U, q, h)                   # each pose its own row


def test_gravity_torques_match_virtual_work(puma, rng):
    m = MeasurementModel(puma)
    q = poses(rng)
    loads = m.loads(m.kin.forward(q), m.context(len(q)))
    np.testing.assert_allclose(loads.joint_torque_nm, gravity_torque_by_virtual_work(m, q), atol=1e-6)


def test_joint_compliance_follows_gravity_torque(puma, rng):
    k = 13061.24                                             # thesis K3 below 100 lb.in, in N m / rad
    m = MeasurementModel(puma, [JointCompliance(3, k)])
    q = poses(rng)
    ev = m.evaluate(q)
    arm = ThesisPuma.from_toml(resources.files("calib") / "data" / "puma560.toml")
    tau3 = np.array([arm.gravity_torques(qi)[2] for qi in q])          # plain cross products, not the model
    np.testing.assert_allclose(ev.theta_rad[:, 2] - q[:, 2], tau3 / k, rtol=1e-6, atol=1e-12)
    # a payload adds its own torque: more sag
    heavy = m.evaluate(q, m.context(len(q), payload_kg=5.0))
    assert np.all(np.abs(heavy.theta_rad[:, 2] - q[:, 2]) >= np.abs(ev.theta_rad[:, 2] - q[:, 2]) - 1e-12)


def test_two_slopes_and_dead_zone_against_the_thesis_curve(puma, rng):
    """The thesis's K3 (1.156e5 lb in/rad below 100 lb in, 1.223e5 above) under gravity plus an applied torque: the
    torque from plain cross products of the link weights and the deflection read off the thesis's two-slope curve
    (the independent generator); the dead zone puts unloading one h above loading."""
    k1, k2, tb, h = 1.156e5 * NM_PER_LBIN, 1.223e5 * NM_PER_LBIN, 100 * NM_PER_LBIN, 0.005 * DEG
    m = MeasurementModel(puma, [JointCompliance(3, k1, k2, tb, h)])
    n = 40
    q = poses(rng, n)
    applied = rng.uniform(-30.0, 30.0, n)
    e3 = np.array([0, 0, 1.0, 0, 0, 0])
    defl = {}
    for ld in (-1.0, 0.0, 1.0):
        ctx = m.context(n, joint_torque_nm=np.outer(applied, e3), load_direction=ld * np.ones((n, 6)))
        defl[ld] = m.evaluate(q, ctx).theta_rad[:, 2] - q[:, 2]
    arm = ThesisPuma.from_toml(resources.files("calib") / "data" / "puma560.toml")
    curve = fake.JointCompliance(3, k1, k2, tb)
    tau = np.array([arm.gravity_torques(qi)[2] for qi in q]) + applied
    assert np.any(np.abs(tau) < tb) and np.any(np.abs(tau) > tb)         # both slopes are exercised
    np.testing.assert_allclose(defl[0.0], [curve.deflection(t) for t in tau], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(defl[-1.0] - defl[1.0], h, atol=1e-15)


def test_cross_coupling_is_linear_in_the_source_joint(puma, rng):
    m = MeasurementModel(puma, [CrossCoupling(6, 5, 0.1802)])
    q = poses(rng)
    d = m.evaluate(q).theta_rad - q
    np.testing.assert_allclose(d[:, 5], 0.1802 * q[:, 4], atol=1e-15)


def test_thermal_growth_scales_every_length(puma, rng):
    kappa = 23e-6
    m = MeasurementModel(puma, [ThermalDrift(kappa, 20.0)])
    q = poses(rng, 10)
    hot = m.points(q, m.context(10, temperature_c=35.0))
    scaled = m.kin.nominal.copy()
    scaled[m.length_idx] *= 1 + kappa * 15.0
    np.testing.assert_allclose(hot, m.kin.points(q, scaled), atol=1e-9)
    np.testing.assert_allclose(m.points(q, m.context(10, temperature_c=20.0)), m.kin.points(q), atol=1e-12)


def test_link_compliance_bends_down_and_grows_with_load(puma, rng):
    ei = 2.0e11
    m = MeasurementModel(puma.with_tool({"P": [0, 0, 100.0]}), [LinkCompliance(2, ei)])
    rigid = MeasurementModel(puma.with_tool({"P": [0, 0, 100.0]}))
    q = np.tile([0.0, 0.0, np.pi / 2, 0, 0, 0], (2, 1))    # upper arm horizontal
    ctx = m.context(2, payload_kg=np.array([0.0, 10.0]))
    d = m.points(q, ctx) - rigid.points(q)
    assert d[0, 2] < 0 and d[1, 2] < d[0, 2]
    # the payload's share follows F L^3 / (3 EI) at the link end plus the slope carried to the tool
    extra = d[1] - d[0]
    L = np.hypot(432.0, 149.1)
    assert abs(extra[2]) > 10 * G0_M_S2 * L ** 3 / (3 * ei) * 0.5


@pytest.mark.parametrize("with_link", [False, True])
def test_full_jacobian_matches_finite_differences_for_every_effect(puma, rng, with_link):
    effects = [TransmissionError(4, 0.9, [0.05 * DEG, 0.01 * DEG], [0.02 * DEG]), Backlash(2, 0.02 * DEG),
               CrossCoupling(6, 5, 0.001), ThermalDrift(20e-6), JointCompliance(4, 2e4, 1.7e4, 5.0, 1e-4)]
    if with_link:
        # the bending displacement is carried at the true joint angles; only its own parameter's column is exact
        effects = [LinkCompliance(4, 5e10)]
    m = MeasurementModel(puma.with_tool({"P": [40.0, 10.0, 90.0]}), effects)
    n = 30
    q = poses(rng, n)
    ctx = m.context(n, direction=rng.choice([-1.0, 1.0], (n, 6)), load_direction=rng.choice([-1.0, 1.0], (n, 6)),
                    temperature_c=rng.uniform(10, 30, n), tool_force_n=rng.normal(0, 20, (n, 3)))
    theta = m.nominal
    J = m.evaluate(q, ctx, theta, jacobian=True).jacobian
    for i, name in enumerate(m.names):
        if name.startswith(("j", "base", "tool")) and not name.startswith("joint"):
            continue                                         # geometric columns: covered in test_kinematics
        h = max(abs(theta[i]) * 1e-4, 1e-7 if name.endswith("_rad") else 1e-12)
        d = np.zeros(m.P)
        d[i] = h
        fd = (m.points(q, ctx, theta + d) - m.points(q, ctx, theta - d)) / (2 * h)
        np.testing.assert_allclose(J[:, :, i], fd, rtol=1e-4, atol=1e-7 * np.abs(fd).max(), err_msg=name)


def test_geometric_jacobian_includes_the_torque_change(puma, rng):
    """Joint compliance deflects with the gravity torque, which itself moves with every geometric parameter."""
    m = MeasurementModel(puma.with_tool({"P": [30.0, 0.0, 80.0]}), thesis_effects())
    n = 20
    q = poses(rng, n)
    ctx = m.context(n, payload_kg=3.0)
    theta = m.nominal
    J = m.evaluate(q, ctx, theta=theta, jacobian=True, torque_derivative=True).jacobian
    steps = np.array([1e-6 if name.endswith("_rad") else 1e-4 for name in m.names])
    fd_all = numeric_jacobian(lambda th: m.points(q, ctx, th), theta, steps)
    for i in range(m.n_geometric):
        fd = fd_all[:, :, i]
        np.testing.assert_allclose(J[:, :, i], fd, atol=2e-6 * max(1.0, np.abs(fd).max()), err_msg=m.names[i])


@pytest.mark.parametrize("softer", [1.0, 30.0])
def test_torque_term_is_left_out_only_where_it_is_small(puma, rng, softer):
    """The rule of calib.model.torque_term_matters: with the thesis's compliances the bound eps = max c |M| is below
    1 % and the term is left out -- each geometric column then differs from the exact one by about eps; a robot 30x
    more compliant keeps it, and its default Jacobian is the exact one."""
    effects = thesis_effects()
    for e in effects:
        if isinstance(e, JointCompliance):
            e.values[:2] *= softer
    m = MeasurementModel(puma.with_tool({"P": [30.0, 0.0, 80.0]}), effects)
    n = 20
    q = poses(rng, n)
    ctx = m.context(n, payload_kg=3.0)
    exact = m.evaluate(q, ctx, jacobian=True, torque_derivative=True).jacobian
    without = m.evaluate(q, ctx, jacobian=True, torque_derivative=False).jacobian
    ev = m.evaluate(q, ctx, jacobian=True)
    eps = torque_term_size(m.torque_gain(ev), ev.loads)
    g = slice(0, m.n_geometric)
    col = np.linalg.norm(exact[:, :, g] - without[:, :, g], axis=(0, 1)) / np.linalg.norm(exact[:, :, g], axis=(0, 1))
    assert 0.1 * eps < col.max() < 3 * eps                   # the bound describes the term's size
    if eps < TORQUE_TERM_THRESHOLD:
        assert softer == 1.0
        np.testing.assert_array_equal(ev.jacobian, without)
    else:
        assert softer > 1.0
        np.testing.assert_array_equal(ev.jacobian, exact)


def test_jacobian_completed_later_equals_the_one_asked_at_once(puma, rng):
    """evaluate() without a Jacobian keeps its pass; complete_jacobian() adds the same Jacobian (identify's reuse)."""
    m = MeasurementModel(puma.with_tool({"P": [30.0, 0.0, 80.0]}), thesis_effects())
    q = poses(rng, 15)
    ctx = m.context(15, payload_kg=2.0)
    once = m.evaluate(q, ctx, jacobian=True, torque_derivative=True)
    later = m.evaluate(q, ctx)
    assert later.jacobian is None
    m.complete_jacobian(later, torque_derivative=True)
    np.testing.assert_array_equal(later.jacobian, once.jacobian)
    np.testing.assert_array_equal(later.joint_jacobian, once.joint_jacobian)
    np.testing.assert_array_equal(later.point_mm, once.point_mm)


def test_completing_the_jacobian_later_reads_no_caller_array(puma, rng):
    """identify() evaluates, then asks for the Jacobian; a caller that reuses its theta or q array in between (an
    optimiser's step in place) must not change the Jacobian of the evaluation already made."""
    m = MeasurementModel(puma.with_tool({"P": [30.0, 0.0, 80.0]}), thesis_effects())
    q = poses(rng, 15)
    ctx = m.context(15, payload_kg=2.0)
    theta = m.nominal.copy() + rng.normal(0, 1e-3, m.P)
    once = m.evaluate(q, ctx, theta=theta, jacobian=True, torque_derivative=True)
    later = m.evaluate(q, ctx, theta=theta)
    theta += 0.05
    q += 0.1
    m.complete_jacobian(later, torque_derivative=True)
    np.testing.assert_array_equal(later.jacobian, once.jacobian)
    np.testing.assert_array_equal(later.joint_jacobian, once.joint_jacobian)


def test_two_effects_of_one_kind_on_one_joint_get_distinct_names(puma):
    m = MeasurementModel(puma, [TransmissionError(4, 0.9, [0.01], [0.0]), TransmissionError(4, 1.8, [0.02], [0.0])])
    assert len(set(m.names)) == len(m.names)
    assert m.nominal[m.index["transmission_error.j4.s1_rad"]] == 0.01
    assert m.nominal[m.index["transmission_error.j4@2.s1_rad"]] == 0.02


# -- the registry (contract C1) -------------------------------------------------------------------------------------
def test_every_registered_kind_round_trips_through_text_json_and_zero():
    from calib.effects import EFFECTS, effect_from_spec, effect_from_text, effect_spec, make_effect
    assert {"transmission_error", "joint_compliance", "backlash", "cross_coupling", "link_compliance",
            "thermal_drift"} <= set(EFFECTS)
    for kind, cls in EFFECTS.items():
        assert cls.kind == kind
        joint = 3 if cls.has_joint else None
        opts = make_effect(kind, joint).option_values()                # the kind's own defaults
        if kind in ("transmission_error", "cross_coupling"):
            opts.update({k: v for k, v in {"order": 0.9, "harmonics": 2, "source": 5}.items() if k in cls.options})
        fields = ([joint] if cls.has_joint else []) + [opts[k] for k in cls.options]
        e = effect_from_text(":".join([kind] + [f"{f:g}" for f in fields]))
        assert type(e) is cls and e.joint == joint and e.option_values() == opts
        e.values = np.arange(1.0, len(e.values) + 1) * 1e-6
        again = effect_from_spec(json.loads(json.dumps(effect_spec(e))), dict(zip(e.qualified_names(), e.values)),
                                 "model.json: effects[0]")
        assert again.qualified_names() == e.qualified_names() and np.array_equal(again.values, e.values)
        assert again.option_values() == e.option_values()
        z = make_effect(kind, e.joint, **e.option_values())
        assert z.qualified_names() == e.qualified_names()


def test_an_unknown_kind_lists_the_known_ones():
    from calib.effects import EFFECTS, effect_from_spec, effect_from_text, make_effect
    from calib.errors import RobocalError
    for call in (lambda: effect_from_text("friction:2"), lambda: make_effect("friction", 2),
                 lambda: effect_from_spec({"type": "friction", "joint": 2}, {}, "m.json: effects[1]")):
        with pytest.raises(RobocalError) as exc:
            call()
        assert "unknown kind 'friction'" in str(exc.value) and all(k in str(exc.value) for k in EFFECTS)


def test_a_new_effect_is_one_class_registered_once(puma):
    """A kind registered once is built by the text, the scenario, the model JSON and the model without other edits."""
    from calib.effects import EFFECTS, Effect, effect_from_text, register_effect
    from calib.tomlspec import Field
    from sim.twin import parse_scenario


    class ZeroOffsetDrift(Effect):
        kind = "zero_offset_drift"
        param_names = ("offset_rad",)
        scenario_fields = {"joint": Field("int", required=True, min=1), "offset_deg": Field("number", default=0.0)}

        def __init__(self, joint, offset_rad):
            super().__init__(joint, {"offset_rad": offset_rad})

        @classmethod
        def zero(cls, joint=None):
            return cls(joint, 0.0)

        @classmethod
        def from_table(cls, c):
            return cls(c["joint"], c["offset_deg"] * DEG)

        def joint_delta(self, q, ctx, loads, values):
            delta, grad = np.zeros_like(q), np.zeros(q.shape + (1,))
            grad[:, self.joint - 1, 0] = 1.0
            return delta + grad[..., 0] * values[0], grad

    register_effect(ZeroOffsetDrift)
    try:
        with pytest.raises(TypeError, match="registered twice"):
            register_effect(type("Again", (ZeroOffsetDrift,), {}))
        e = effect_from_text("zero_offset_drift:2")
        sc = parse_scenario('[[effect]]\ntype = "zero_offset_drift"\njoint = 2\noffset_deg = 0.1\n')
        assert sc.effects[0].values[0] == pytest.approx(0.1 * DEG)
        m = MeasurementModel(puma, [e])
        q = np.zeros((1, 6))
        theta = m.nominal
        theta[m.index["zero_offset_drift.j2.offset_rad"]] = 0.01
        assert m.evaluate(q, theta=theta).theta_rad[0, 1] == pytest.approx(0.01)
    finally:
        EFFECTS.pop("zero_offset_drift", None)


def test_an_effect_flagged_own_joint_only_changes_its_own_joint_alone(puma, rng):
    """``own_joint_only`` lets the Jacobian take the joint's column times the derivative's row instead of a product
    over every joint: every kind that claims it changes no other joint (values off zero, random poses, loads and
    directions); the finite-difference test above checks the columns that shortcut writes."""
    from calib.effects import EFFECTS, make_effect
    flagged = [k for k, cls in EFFECTS.items() if cls.stage == "joint" and cls.own_joint_only]
    assert {"transmission_error", "joint_compliance", "backlash", "cross_coupling"} <= set(flagged)
    n = 25
    q = poses(rng, n)
    for kind in flagged:
        opts = {"order": 0.9, "harmonics": 2, "source": 5} if kind in ("transmission_error", "cross_coupling") else {}
        e = make_effect(kind, 3, **{k: v for k, v in opts.items() if k in EFFECTS[kind].options})
        e.values = rng.uniform(0.5, 1.5, len(e.values)) * 1e-4
        m = MeasurementModel(puma, [e])
        ctx = m.context(n, direction=rng.choice([-1.0, 1.0], (n, 6)),
                        load_direction=rng.choice([-1.0, 1.0], (n, 6)), tool_force_n=rng.normal(0, 20, (n, 3)))
        loads = m.evaluate(q, ctx, m.nominal).loads
        delta, grad = e.joint_delta(q, ctx, loads, e.values)
        others = [j for j in range(6) if j != 2]
        assert np.any(grad[:, 2] != 0), kind
        assert not np.any(delta[:, others]) and not np.any(grad[:, others]), kind
