"""The emulated bench takes its physics from geometry (contract C3): a load is a mass at a point on a link, and joint
deflections, link bending, gauge readings and targets follow from the twin's one model.  Truth from plain cross
products and the cantilever formula (tests/fakes/point_loads.py), not from the model under test."""
from __future__ import annotations

import numpy as np
import pytest

from sim.emulate.twin_world import TwinWorld
from sim.emulate.bench import EmulatedBench
from acq.session.steps import Step, TargetSpec
from sim.twin import Twin, parse_scenario
from calib.units import DEG
from tests.fakes.oracle.beam import cantilever_deflection
from tests.fakes.point_loads import frames, point_force_torques

K3, K4, EI2 = 13000.0, 25000.0, 2.0e11
SCENARIO = f"""
[twin]
seed = 1
[noise]
angles = false
encoder_quantisation = false
[[effect]]
type = "joint_compliance"
joint = 3
stiffness_nm_per_rad = {K3}
[[effect]]
type = "joint_compliance"
joint = 4
stiffness_nm_per_rad = {K4}
[[effect]]
type = "link_compliance"
joint = 2
ei_nmm2 = {EI2}
"""


@pytest.fixture
def bench():
    twin = Twin(parse_scenario(SCENARIO))
    return EmulatedBench(TwinWorld(twin, seed=0, gauge_sigma_mm=0.0))


def _step(pose, setup, key="s"):
    return Step(key=key, procedure="anything", title="", instruction="", pose_deg=tuple(pose), setup=setup)


def _joint_angles(bench):
    w = bench.world
    _, q = w.twin.encoder(w.joint_angles_rad()[None])
    return w.twin.model.evaluate(q, w.context(), w.twin.theta).theta_rad[0]


def _deflection(bench, pose, setup):
    bench.prepare(_step(pose, {}), {})
    free = _joint_angles(bench)
    bench.prepare(_step(pose, setup), {})
    return _joint_angles(bench) - free


def test_a_hung_mass_turns_each_joint_by_its_torque_over_stiffness(bench):
    pose = (0.0, -90.0, 0.0, 90.0, 90.0, 90.0)
    load = {"link": 4, "point_mm": [500.0, 0.0, 0.0], "mass_kg": 3.0}
    d = _deflection(bench, pose, {"loads": [load]})
    g = bench.world.twin.model.gravity_n_per_kg(bench.world.twin.theta)
    tau = point_force_torques(bench.world.robot, np.asarray(pose) * DEG, 4, load["point_mm"], 3.0 * g)
    assert abs(tau[3]) > 10.0                                   # the lever is level across joint 4's axis
    np.testing.assert_allclose(d[[2, 3]], tau[[2, 3]] / [K3, K4], rtol=2e-3)
    np.testing.assert_allclose(d[[0, 1, 4, 5]], 0.0, atol=1e-15)


def test_a_load_on_a_vertical_axis_moves_nothing_about_it(bench):
    """READY: joint 4's axis is vertical; the old compliance step (load on a lever) is a mass on link 4 and the
    joint does not turn, whatever the step says."""
    legacy = {"joint": 4, "load_n": 45.0, "lever_mm": 500.0, "theta_i_deg": 0.0, "load_direction": 1}
    d = _deflection(bench, (0.0, -90.0, 90.0, 0.0, 0.0, 0.0), legacy)
    assert abs(d[3]) < 1e-15 and abs(d[2]) > 1e-4


def test_operator_mass_replaces_the_first_load(bench):
    pose = (0.0, -90.0, 0.0, 90.0, 90.0, 90.0)
    setup = {"loads": [{"link": 4, "point_mm": [500.0, 0.0, 0.0], "mass_kg": 1.0}], "load_direction": {"4": 1}}
    bench.prepare(_step(pose, setup), {"load_kg": 2.0})
    two = _joint_angles(bench)
    bench.prepare(_step(pose, setup), {})
    one = _joint_angles(bench)
    bench.prepare(_step(pose, {}), {})
    none = _joint_angles(bench)
    np.testing.assert_allclose(two[3] - none[3], 2 * (one[3] - none[3]), rtol=1e-9)


def test_gauges_read_the_cantilever_deflection_of_their_points(bench):
    """Link 2 level: a mass at a on the link, gauges at x along it read P x^2 (3a - x) / 6 EI along gravity."""
    pose = np.array([0.0, 0.0, 90.0, 0.0, 0.0, 0.0])
    T = frames(bench.world.robot, pose * DEG)
    o1, o2, R2 = T[1][:3, 3], T[2][:3, 3], T[2][:3, :3]
    z1 = T[1][:3, 2]
    o1 = o1 + ((o2 - o1) @ z1) * z1                                      # the link leaves joint 2's axis here
    L = np.linalg.norm(o2 - o1)
    u = (o2 - o1) / L
    on = lambda x: (R2.T @ (o1 + u * x - o2)).tolist()            # noqa: E731  frame-2 coordinates
    a, mass, xs = 430.0, 15.0, (150.0, 280.0, 400.0)
    down = [0.0, 0.0, -1.0]
    step = _step(pose, {"loads": [{"link": 2, "point_mm": on(a), "mass_kg": mass}],
                        "gauges": [{"name": f"g{i}", "link": 2, "point_mm": on(x), "axis": down}
                                   for i, x in enumerate(xs)]})
    got = bench.read_gauges(step)
    P = mass * 9.80665
    for i, x in enumerate(xs):
        want = cantilever_deflection(x, a, P, EI2)                          # the oracle's integrated beam
        assert got[f"g{i}_mm"] == pytest.approx(want, abs=1.5e-4), (x, got)
    assert got["g2_mm"] > 0.01
    # the old link-compliance step reads the same gauges through the same translation
    legacy = _step(pose, {"joint": 2, "load_n": P, "load_x_mm": a, "gauges_x_mm": list(xs)})
    old = bench.read_gauges(legacy)
    assert [old[f"gauge{i + 1}_mm"] for i in range(3)] == pytest.approx([got[f"g{i}_mm"] for i in range(3)],
                                                                         abs=1e-4)


def test_targets_on_a_link_ride_with_that_link_only(bench):
    w = bench.world
    bench.aim(TargetSpec("P3", tool_mm=(300.0, 0.0, 0.0), link=3))
    bench.prepare(_step((0.0, -90.0, 90.0, 0.0, 0.0, 0.0), {}), {})
    p0 = w.target_mm()
    bench.prepare(_step((0.0, -90.0, 90.0, 40.0, -30.0, 70.0), {}), {})
    # the wrist's weight moves with it and joint 3 gives way by a fraction of a micrometre: nothing more
    np.testing.assert_allclose(w.target_mm(), p0, atol=1e-3)
    bench.prepare(_step((0.0, -90.0, 80.0, 40.0, -30.0, 70.0), {}), {})
    assert np.linalg.norm(w.target_mm() - p0) > 10.0


def test_a_steps_targets_evaluated_together_are_the_points_one_by_one():
    """The bench evaluates a step's flange targets (A1, A2) in one pass of the twin's model when it prepares the
    step: each point must be exactly what the world computes for that target alone at the same state, and a move
    must forget them."""
    tw = Twin(seed=4)
    world = TwinWorld(tw, seed=4)
    bench = EmulatedBench(world)
    a1, a2 = TargetSpec("A1", tool_mm=(80.0, 0.0, 150.0)), TargetSpec("A2", tool_mm=(-80.0, 10.0, 150.0))
    step = Step("te/x", "transmission", "", "", pose_deg=(10.0, -40.0, 170.0, 30.0, 20.0, 40.0), targets=(a1, a2))
    bench.prepare(step, {})
    assert len(world._ahead) == 2
    together = {}
    for t in (a1, a2):
        bench.aim(t)
        together[t.name] = world.target_mm()
    for t in (a1, a2):
        alone = world._point(None, t.tool_mm)
        np.testing.assert_array_equal(together[t.name], alone)
    world.command(np.asarray(step.pose_deg) * DEG + 0.01)
    assert world._ahead == {}
    bench.aim(a1)
    assert not np.array_equal(world.target_mm(), together["A1"])


def test_the_kept_readings_and_context_follow_every_change_of_state():
    """The world keeps the encoder's readings and the pose context of the present state for its evaluations; after
    a move, a hung mass, a changed payload, each point is exactly what a world built fresh at that state computes
    (the same model, nothing stale)."""
    from calib.loads import HungMass
    tw = Twin(seed=5)
    world = TwinWorld(tw, seed=5)
    tool = world.default_tool_mm
    q = np.radians([10.0, -40.0, 170.0, 30.0, 20.0, 40.0])
    changes = [lambda w: w.command(q), lambda w: w.hang([HungMass(6, (0.0, 0.0, 120.0), 2.0)], np.ones(6)),
               lambda w: w.command(q + 0.02), lambda w: w.set_load(payload_kg=1.5),
               lambda w: w.hang([HungMass(3, (20.0, 0.0, 300.0), 5.0)], -np.ones(6))]
    done = []
    for change in changes:
        world._point(None, tool), world._point(3, (0.0, 50.0, 100.0), loaded=False)      # fill what it keeps
        change(world)
        done.append(change)
        fresh = TwinWorld(tw, seed=5)
        for c in done:
            c(fresh)
        for args in ((None, tool), (3, (0.0, 50.0, 100.0))):
            for loaded in (True, False):
                np.testing.assert_array_equal(world._point(*args, loaded=loaded), fresh._point(*args, loaded=loaded))
