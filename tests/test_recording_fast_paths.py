"""Paths written twice for the demo's recording speed give the same floats as the general path, bit for bit.

Each test runs the fast path and the general one on the same inputs and asserts exact equality (``array_equal``, not
``allclose``): the demo's printed figures and the twin's truths must not move by a last bit.  A test fails as soon as
the two copies drift apart.
"""
import numpy as np

from calib.kinematics import Kinematics


def _bits(a) -> bytes:
    return np.ascontiguousarray(a, float).tobytes()


def test_forward_fixed_terms_equal_the_per_pose_path(puma, rng):
    """One parameter vector (its link and base terms kept between calls) gives the floats of the same vector given
    per pose (computed afresh every call), for one pose and for several, with the tool point changed between calls
    (the kept terms leave the tool out) and with a parameter moved (a new entry, not a stale one)."""
    kin = Kinematics(puma)
    p0 = kin.nominal + rng.normal(0, 1e-3, kin.P)
    for trial in range(6):
        p = p0.copy()
        p[-3:] += rng.normal(0, 50, 3)                  # another target on the flange: the same kept terms
        if trial == 4:
            p[7] += 1e-6                               # another parameter vector: terms of its own
        for N in (1, 3):
            q = rng.uniform(-np.pi, np.pi, (N, kin.n))
            fast = kin.forward(q, p)
            again = kin.forward(q, p)
            general = kin.forward(q, np.repeat(p[None], N, 0))
            for a, b in ((fast, general), (again, general)):
                assert _bits(a.point) == _bits(b.point)
                assert _bits(a._R) == _bits(b._R) and _bits(a._t) == _bits(b._t)
            assert _bits(kin.element_jacobian(fast)) == _bits(kin.element_jacobian(general))


def test_sample_std_of_few_values_is_numpys(rng):
    """The repeat-spread check's standard deviation of 2..7 values (a step's repeats) in plain floats is numpy's
    ``std(ddof=1)`` to the last bit: readings near 0, near 2 pi, wrapped differences and values a few ulps apart."""
    from acq.session.checks import sample_std
    from calib.angles import wrap_angle, wrap_float
    for n in range(2, 12):
        for trial in range(300):
            scale = (1e-5, 1.0, 6.0, 1e-12)[trial % 4]
            x = rng.normal(rng.uniform(-7, 7), scale, n)
            assert sample_std(x.tolist()) == float(np.std(x, ddof=1))
            d = [wrap_float(v - x[0]) for v in x.tolist()]
            assert sample_std(d) == float(np.std(wrap_angle(x - x[0]), ddof=1))


def test_vector_norm_is_numpys(rng):
    """The session checks' distances (miss sigma, plausibility) are ``np.linalg.norm``'s floats to the last bit: 3-D
    differences of points mm to m apart, tiny and huge, and a 2-D or integer array through numpy itself."""
    from acq.session.checks import vector_norm
    for trial in range(3000):
        scale = (1e-9, 1e-3, 1.0, 2e3, 1e12)[trial % 5]
        x = rng.normal(0.0, scale, 3 if trial % 7 else rng.integers(1, 12))
        assert vector_norm(x) == float(np.linalg.norm(x))
        y = x - rng.normal(0.0, scale, x.size)
        assert vector_norm(y) == float(np.linalg.norm(y))
    m = rng.normal(0.0, 1.0, (3, 2))
    assert vector_norm(m) == float(np.linalg.norm(m))
    assert vector_norm(np.array([3, 4])) == 5.0


def test_kept_load_structure_gives_the_fresh_arrays(rng, monkeypatch):
    """The twin's model (compliances, transmission errors, coupling) evaluated one pose at a time with hung masses,
    which joint carries which body kept between calls, gives the floats of the same evaluation with that structure
    worked out afresh: points, true angles, torques, tip forces and the Jacobian, bit for bit."""
    from calib.effects import PoseContext
    from calib.model import MeasurementModel
    from sim.twin import Twin, load_scenario

    twin = Twin(load_scenario(None), seed=0)
    m = twin.model
    n = m.robot.n

    def run():
        out = []
        for k in range(8):
            q = rng.uniform(-1.5, 1.5, (1, n))
            ctx = PoseContext(1, n, direction=np.sign(rng.normal(size=(1, n))),
                              point_force_link=np.array([3, 6])[: k % 3],
                              point_force_mm=rng.normal(0, 100, (1, k % 3, 3)),
                              point_force_n=rng.normal(0, 20, (1, k % 3, 3)))
            tool = rng.normal(0, 80, 3)
            ev = m.evaluate(q, ctx, twin.theta, jacobian=True, tool_mm=tool)
            out += [ev.point_mm, ev.theta_rad, ev.loads.joint_torque_nm, ev.loads.tip_force_n, ev.jacobian]
        return out

    state = rng.bit_generator.state
    kept = run()                                         # the structures worked out, then kept
    rng.bit_generator.state = state
    again = run()                                        # every one from the cache
    rng.bit_generator.state = state
    monkeypatch.setattr(MeasurementModel, "_structure", lambda self, fp, link: None)
    fresh = run()
    assert len(m._structures) > 0
    for a, b, c in zip(kept, again, fresh):
        assert _bits(a) == _bits(c) and _bits(b) == _bits(c)


def test_station_rotation_of_repeated_angles_is_elementwise(rng, monkeypatch):
    """Batches of sightings from levelled stations (a tilt repeated throughout, as the ruler fit's Jacobian has them)
    take a repeated angle's cosine and sine once: the rotations and readings equal the elementwise ones bit for bit
    -- 0.0 and -0.0 kept apart, a value repeated among others not mistaken for a constant."""
    import calib.theodolite as th
    shape = (37, 41)
    yaw = rng.uniform(-4, 4, shape)
    cases = [(np.full(shape, 1e-4), np.full(shape, -2e-5)), (np.zeros(shape), np.full(shape, -0.0)),
             (np.where(rng.random(shape) < 0.5, 0.0, -0.0), np.full(shape, 3e-4)),
             (np.full(shape, 2e-4), np.where(rng.random(shape) < 0.99, 1e-4, 1e-4 + 1e-19))]
    params = np.concatenate([rng.normal(0, 500, shape + (3,)), yaw[..., None], np.full(shape + (2,), 1e-5),
                             np.full(shape + (3,), 2e-6)], -1)
    points = rng.normal(0, 2000, shape + (3,))

    def run():
        return [th.station_rotation(yaw, tx, ty) for tx, ty in cases] + list(th.observe_params(params, points, 2))

    fast = run()
    monkeypatch.setattr(th, "SAME_ANGLE_FROM", 10 ** 9)             # every angle through the elementwise ufuncs
    for a, b in zip(fast, run()):
        assert _bits(a) == _bits(b)


def test_forward_fixed_terms_follow_a_vector_stepped_in_place(puma, rng):
    """An optimiser steps its parameter vector in place: the kept terms are the new vector's, not the old one's."""
    kin = Kinematics(puma)
    p = kin.nominal.copy()
    first = p.copy()
    q = rng.uniform(-np.pi, np.pi, (1, kin.n))
    kin.forward(q, p)
    p[:6] += 1e-3                                   # the base moved, in the same array
    for v in (p, first):                            # the moved vector, then the first one again
        assert _bits(kin.forward(q, v).point) == _bits(Kinematics(puma).forward(q, v.copy()).point)


def test_mean_rows_is_numpys_mean(rng):
    """The encoder windows' mean joint readings (runner event, pose check) are ``np.mean(a, 0)``'s floats to the
    last bit: windows of 1 to 600 samples of six joints, C- and Fortran-ordered, a view, and other arrays through
    numpy itself."""
    from acq.session.rig import mean_rows
    for n in list(range(1, 20)) + [127, 128, 129, 250, 251, 600]:
        a = rng.normal(0.0, 2.0, (n, 6)) * 10.0 ** rng.integers(-6, 4, (1, 6))
        for x in (a, np.asfortranarray(a), a[::-1], a[:, ::2]):
            assert _bits(mean_rows(x)) == _bits(np.mean(x, 0))
    ints = rng.integers(0, 1 << 20, (9, 6))
    assert _bits(mean_rows(ints)) == _bits(np.mean(ints, 0))
