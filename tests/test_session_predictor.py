"""The runner's predictor primed with a plan (one vectorised evaluation per target) predicts what it predicts one
step at a time: the same points and plausibility sigmas, for steps it was primed with and steps it was not."""
from __future__ import annotations

import numpy as np

from app.demo import demo_setup
from acq.session.procedures import all_steps
from acq.session.setup import predictor, session_setup
from sim.twin import Twin, load_scenario


def _plan_steps():
    twin = Twin(load_scenario(), seed=0)
    setup = session_setup(demo_setup(twin), twin.robot)
    rng = np.random.default_rng(3)
    q = np.array([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]) + rng.uniform(-20, 20, (6, 6))
    plan = {"procedures": ["sweeps", "poses", "compliance"], "sweeps": {"points": 3, "span_deg": 30.0, "joints": [2, 5]},
            "poses": {"q_deg": q.round(3).tolist()}, "compliance": {"joints": [3], "repeats": 1}}
    return twin, setup, all_steps(plan, setup)


def test_primed_predictions_equal_one_at_a_time():
    twin, setup, steps = _plan_steps()
    one, primed = predictor(twin.robot, setup), predictor(twin.robot, setup)
    primed.prime(steps[: len(steps) // 2])               # the rest are predicted one at a time by the primed one too
    n = 0
    for s in steps:
        a, b = one(s), primed(s)
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_allclose(b[k][0], a[k][0], rtol=0, atol=1e-9)
            assert abs(b[k][1] - a[k][1]) <= 1e-9 * a[k][1] and a[k][1] > 0
            n += 1
    assert n >= len(steps) // 2


def test_a_prediction_is_the_callers_to_keep():
    twin, setup, steps = _plan_steps()
    p = predictor(twin.robot, setup)
    p.prime(steps)
    s = next(s for s in steps if p(s))
    first = p(s)
    name = next(iter(first))
    first[name][0][:] = 0.0                              # a caller changing its copy changes no later prediction
    assert np.any(p(s)[name][0] != 0.0)


def test_an_unprimed_pose_is_kept_by_pose():
    """A step predicted without priming (ISO 9283's commands, computed when reached, repeat in every cycle) is kept:
    asked again it gives the same, and a step at another pose gets its own prediction, not the kept one."""
    from dataclasses import replace
    twin, setup, steps = _plan_steps()
    s = next(s for s in steps if s.procedure == "poses")
    moved = replace(s, pose_deg=tuple(v + 7.0 for v in s.pose_deg))
    p = predictor(twin.robot, setup)
    for step in (s, moved, s, moved):
        got, fresh = p(step), predictor(twin.robot, setup)(step)
        assert got.keys() == fresh.keys() and got
        for k in got:
            assert np.array_equal(got[k][0], fresh[k][0]) and got[k][1] == fresh[k][1]
        name = next(iter(got))
        got[name][0][:] = 0.0                            # the caller's copy: the kept point stays as computed
    assert np.linalg.norm(p(s)[name][0] - p(moved)[name][0]) > 10.0
