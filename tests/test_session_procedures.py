"""Procedures in the step vocabulary: levelling and the instrument check with their own checks, the ruler series
that varies R, the registry that replaces name branches."""
from __future__ import annotations

import numpy as np
import pytest

from acq.session import checks as ck
from acq.session.procedures import PROCEDURES, all_steps, procedure_info
from acq.session.setup_types import mark_index, mark_names
from acq.session.setup import standard_setup
from acq.session.steps import Step
from calib.setup_plan import into_setup, SetupPlan
from calib.units import ARCSEC

LIMITS = ck.DEFAULT_LIMITS


def test_levelling_steps_per_station_and_their_check():
    setup = standard_setup()
    setup["stations"]["names"] = ["West", "East"]
    steps = all_steps({"procedures": ["levelling"]}, setup)
    assert [s.key for s in steps] == ["level/West", "level/East"]
    (check,) = procedure_info("levelling").checks
    ok = check(steps[0], [], {"tilt_cross_arcsec": 3.0, "tilt_length_arcsec": -9.0}, LIMITS)
    bad = check(steps[1], [], {"tilt_cross_arcsec": 3.0, "tilt_length_arcsec": -25.0}, LIMITS)
    assert ok[0].passed and ok[0].value == 9.0
    assert not bad[0].passed and bad[0].value == 25.0 and "East" in bad[0].message
    assert not check(steps[0], [], {}, LIMITS)[0].passed           # nothing entered is not a level


def _reading(st, face, hz, v):
    return {"station": st, "target": "F", "face": face, "hz_rad": hz, "v_rad": v}


def test_instrument_check_recovers_collimation_and_index():
    """Readings made by hand: face I at Hz0 + c, V0 + i; face II at Hz0 + 180 - c, 360 - V0 + i."""
    c, i = 30 * ARCSEC, 8 * ARCSEC
    hz0, v0 = 1.0, 1.5
    rows = [_reading("A", 1, hz0 + c, v0 + i), _reading("A", 2, hz0 + np.pi - c, 2 * np.pi - v0 + i),
            _reading("B", 1, hz0, v0), _reading("B", 2, hz0 + np.pi, 2 * np.pi - v0)]
    (check,) = procedure_info("instrument_check").checks
    out = {x.name: x for x in check(None, rows, {}, LIMITS)}
    assert not out["instrument A"].passed and abs(out["instrument A"].value - 30.0) < 1e-6
    assert "collimation +30.0\", index +8.0\"" in out["instrument A"].message
    assert out["instrument B"].passed and out["instrument B"].value < 1e-6


def test_ruler_series_varies_R():
    plan = SetupPlan("ruler", {"L_mm": 1610.0, "R_mm": 1860.0, "r1_mm": 930.0, "X1_mm": -300.0, "Y1_mm": 1200.0},
                     {}, "")
    setup = into_setup([plan], standard_setup())
    marks = setup["ruler"]["marks_mm"]
    assert marks == [0.0, 930.0, 1800.0, 1830.0, 1860.0]
    steps = all_steps({"procedures": ["ruler"]}, setup)
    by_placement: dict[int, list] = {}
    for s in steps:
        by_placement.setdefault(s.meta["placement"], []).append(marks[s.meta["mark"]])
    # each placement: C, D, its own E and the last mark; R (C to its own E) differs from placement to placement
    assert by_placement == {0: [0.0, 930.0, 1800.0, 1860.0], 1: [0.0, 930.0, 1830.0, 1860.0], 2: [0.0, 930.0, 1860.0]}
    assert mark_names(3) == ("C", "D", "E") and mark_names(5) == ("C", "D", "E1", "E2", "E3")
    assert [mark_index(n) for n in mark_names(5)] == [0, 1, 2, 3, 4] and mark_index("E") == 2


def test_registry_knows_every_procedure():
    for name in PROCEDURES:
        assert procedure_info(name).steps is PROCEDURES[name]
    assert procedure_info("sweep").steps is PROCEDURES["sweeps"]          # a step's shorter name
    assert procedure_info("ruler").refits_stations
    assert not procedure_info("sweep").refits_stations
    assert procedure_info("imported-something").checks == ()


def test_loads_and_gauges_in_the_step_vocabulary():
    from calib.loading import load_robot
    from acq.session.setup import session_setup
    setup = session_setup(standard_setup(), load_robot())
    steps = all_steps({"procedures": ["compliance", "link_compliance"], "compliance": {"joints": [4]}}, setup)
    loaded = [s for s in steps if s.procedure == "compliance" and s.setup["load_n"] > 0]
    for s in loaded:
        (ld,) = s.setup["loads"]
        assert ld["link"] == 4 and abs(ld["mass_kg"] * 9.80665 - s.setup["load_n"]) < 1e-3
        assert s.setup["tested_joint"] == 4
    link = [s for s in steps if s.procedure == "link_compliance"]
    g = link[0].setup["gauges"]
    assert [x["name"] for x in g] == ["gauge1", "gauge2", "gauge3"]
    assert all(x["link"] == 2 and np.allclose(x["axis"], [0, 0, -1]) for x in g)
    # gauges_x_mm along the link from joint 2's centre = frame-2 x + a2 (the frame sits at the link's far end)
    assert [x["point_mm"][0] + 432.0 for x in g] == link[0].setup["gauges_x_mm"]


def test_steps_as_commands():
    """Every step reads as the command vocabulary; the runner and the bench act on these, not on names."""
    from calib.loading import load_robot
    from acq.session.setup import session_setup
    from acq.session.steps import Ask, Hang, Sight
    setup = session_setup(standard_setup(), load_robot())
    plan = {"procedures": ["levelling", "ruler", "sweeps", "compliance", "link_compliance", "coupling"],
            "sweeps": {"points": 2, "joints": [2]}, "compliance": {"joints": [4]}, "coupling": {"pairs": [[5, 6]]}}
    kinds = {}
    for s in all_steps(plan, setup):
        cmds = s.commands()
        assert isinstance(cmds[0], Ask)
        kinds.setdefault(s.procedure, set()).update(type(c).__name__ for c in cmds)
        for c in cmds:
            if isinstance(c, Hang):
                assert c.load_direction in ({"4": 1}, {"4": -1}, {})
            if isinstance(c, Sight):
                assert c.faces == s.faces and c.repeats == s.repeats
    assert kinds["levelling"] == {"Ask"}
    assert kinds["ruler"] == {"Ask", "Sight"}
    assert kinds["sweep"] == {"Ask", "Move", "Capture", "Sight"}
    assert kinds["compliance"] == {"Ask", "Move", "Hang", "Capture", "Sight"}
    assert kinds["link_compliance"] == {"Ask", "Move", "Hang", "ReadGauges", "Capture"}
    assert kinds["coupling"] == {"Ask", "Move", "Capture"}


def test_link_steps_ask_the_mass_and_reprocess_reads_both():
    """Contract C3: a link step that hangs a mass asks ``load_kg``; the reduction reads the mass entered (as a point
    force with the description's gravity), and an older step's ``load_n`` as that force's mass."""
    from calib.kinematics import Kinematics
    from calib.loading import load_robot
    from acq.session.rig import c3_setup
    from acq.session.setup import session_setup
    robot = load_robot()
    kin = Kinematics(robot)
    g = float(np.linalg.norm(robot.gravity_m_s2))
    setup = session_setup(standard_setup(), robot)
    link = all_steps({"procedures": ["link_compliance"]}, setup)
    for s in link:
        (inp,) = [i for i in s.inputs if i.name.startswith("load")]
        assert inp.name == "load_kg" and inp.unit == "kg"
        assert inp.suggested == s.setup["loads"][0]["mass_kg"]
        assert abs(inp.suggested * g - s.setup["load_n"]) < 1e-2
        assert c3_setup(s.setup, s.pose_deg, {"load_kg": 2.0}, kin)["loads"][0]["mass_kg"] == 2.0
    # an older step: a force on a lever, no loads in the step vocabulary
    old_step = {"joint": 2, "load_n": 10.0, "load_x_mm": 300.0, "gauges_x_mm": [100.0, 200.0]}
    (load,) = c3_setup(old_step, [0.0, 0.0, 90.0, 0.0, 0.0, 0.0], {"load_n": 12.5}, kin)["loads"]
    assert load["mass_kg"] == pytest.approx(12.5 / g) and load["link"] == 2
    # a set-up without load points keeps the old force prompt
    old = {**setup, "link": {k: v for k, v in setup["link"].items() if k != "load_point_mm"}}
    old["link"]["load_point_mm"] = None
    (s0,) = all_steps({"procedures": ["link_compliance"]}, old)[:1]
    assert [i.name for i in s0.inputs][0] == "load_n"


def test_coupling_repeats_have_distinct_stable_keys():
    """Repeats of the coupling run: every repeat its own keys (resume skips what is committed), the first repeat
    with the keys a session without repeats had, the repeat number in meta for reprocess to pool them."""
    setup = standard_setup()
    plan = {"procedures": ["coupling"], "coupling": {"pairs": [[5, 6], [4, 5]], "repeats": 3}}
    steps = all_steps(plan, setup)
    keys = [s.key for s in steps]
    assert len(steps) == 2 * 3 * 4 and len(set(keys)) == len(keys)
    assert keys == [s.key for s in all_steps(plan, setup)]                    # stable
    one = [s.key for s in all_steps({**plan, "coupling": {**plan["coupling"], "repeats": 1}}, setup)]
    assert set(one) <= set(keys) and "coupling/j5k6/with" in one and "coupling/j5k6/with/r2" in keys
    reps = {(s.meta["j"], s.meta["k"], s.meta["repeat"], s.meta["phase"]) for s in steps}
    assert len(reps) == len(steps)


def test_encoder_resolution_steps_are_what_reprocess_reads():
    """The encoder-resolution run: one joint stepped one way, A1 and A2 sighted, the encoder tapped, each step's
    joint in meta (reprocess groups by it)."""
    setup = standard_setup()
    steps = all_steps({"procedures": ["encoder_resolution"],
                       "encoder_resolution": {"joints": [6], "points": 5, "span_deg": 20.0}}, setup)
    assert len(steps) == 5 and all(s.procedure == "encoder_resolution" for s in steps)
    assert all(s.encoders and [t.name for t in s.targets] == ["A1", "A2"] for s in steps)
    assert [s.meta["joint"] for s in steps] == [6] * 5
    q6 = [s.pose_deg[5] for s in steps]
    assert np.all(np.diff(q6) > 0) and abs(q6[-1] - q6[0] - 20.0) < 1e-9
    assert procedure_info("encoder_resolution").steps is PROCEDURES["encoder_resolution"]


def test_resolution_truth_is_the_twins_slope_over_the_run():
    """The emulated truth for the resolution run: the description's resolution when the twin has no running errors,
    tilted by the transmission error (a little, not more than its amplitude allows) when it has."""
    import dataclasses
    from sim.emulate.truth.runs import resolution_in_estimator_terms
    from sim.twin import Twin, load_scenario
    from calib.units import DEG
    sc = load_scenario(None)
    r = sc.robot
    design = 2 * np.pi / abs(r.counts_per_rev[5] * r.gear_ratio[5])       # written out: not the code under test
    q = np.zeros((7, 6))
    q[:, 5] = np.linspace(0.0, 150.0, 7) * DEG
    counts = np.rint(r.counts_from_joint(q))
    signed = counts[:, 5] * np.sign(r.gear_ratio[5])
    cov = np.eye(7) * 1e-10
    bare = Twin(dataclasses.replace(sc, effects=[]), seed=0)
    tv = resolution_in_estimator_terms(bare, 6, counts, signed, cov, design)
    assert abs(tv["scale"] - 1.0) < 1e-4 and abs(tv["rad_per_count"] / design - tv["scale"]) < 1e-12
    tv = resolution_in_estimator_terms(Twin(sc, seed=0), 6, counts, signed, cov, design)
    assert 1e-5 < abs(tv["scale"] - 1.0) < 3e-3
