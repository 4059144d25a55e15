"""The TUI's derived views agree with the session's checks and the estimators (no second copy of the math)."""
import numpy as np

from acq.session.checks import intersect_targets
from app.tui.views import StepData, plot_series
from calib.theodolite import thesis_stations
from calib.units import DEG


def stations():
    a, b = thesis_stations(1609.9, -1.489 * DEG, 1.358 * DEG)
    return {"A": a, "B": b}


def sighted(st, points, step_key="te/j4/00"):
    sd = StepData(step_key, "transmission", {"joint": 4})
    for name, p in points.items():
        for s in ("A", "B"):
            for face in (1, 2):
                hz, v = st[s].observe(np.atleast_2d(p), face)
                sd.readings.append((s, name, face, float(hz[0]), float(v[0])))
    return sd


def test_points_are_the_checks_points():
    st = stations()
    sd = sighted(st, {"P": np.array([500.0, 2800.0, 300.0])})
    rows = [{"station": a, "target": t, "face": f, "hz_rad": h, "v_rad": v} for a, t, f, h, v in sd.readings]
    np.testing.assert_allclose(sd.points(st)["P"], intersect_targets(rows, st)["P"][0])
    np.testing.assert_allclose(sd.points(st)["P"], [500.0, 2800.0, 300.0], atol=1e-6)


def test_te_plot_recovers_a_known_angle_error():
    """Targets turned by the encoder angle plus a known error: the plot shows that error (less its mean)."""
    st = stations()
    centre, n = np.array([600.0, 2700.0, 200.0]), np.array([0.0, 1.0, 0.0])
    enc = np.radians(np.linspace(-40, 40, 9))
    err = np.radians(0.05) * np.sin(0.9 * enc)
    steps = []
    for i, (q, e) in enumerate(zip(enc, err)):
        a = q + e
        u = np.array([np.cos(a), 0.0, -np.sin(a)])
        sd = sighted(st, {"A1": centre + 100 * u + [0, 0, 50], "A2": centre + 300 * u + [0, 0, 50]}, f"te/j4/{i}")
        sd.joint_deg = [0, 0, 0, np.degrees(q), 0, 0]
        steps.append(sd)
    title, _, unit, lines = plot_series("transmission", steps, st)
    got = np.array(lines[0][2])
    np.testing.assert_allclose(got, np.degrees(err - err.mean()), atol=2e-3)


def test_deflection_plot_separates_loading_and_unloading_in_the_units_entered():
    """Loads entered in kg go on the axis as kg; the unloading branch is its own series (meta phase 'unload')."""
    st = stations()
    base = np.array([500.0, 2800.0, 300.0])
    steps = []
    for i, (m, phase) in enumerate([(0, "load"), (5, "load"), (10, "load"), (5, "unload"), (0, "unload")]):
        drop = 0.01 * m + (0.003 if phase == "unload" else 0.0)      # a dead zone between the branches
        sd = sighted(st, {"A1": base - [0.0, 0.0, drop]}, f"compliance/j3/{i}")
        sd.procedure, sd.meta = "compliance", {"joint": 3, "phase": phase}
        sd.inputs["load_kg"] = float(m)
        steps.append(sd)
    title, xlabel, unit, lines = plot_series("compliance", steps, st)
    assert xlabel == "load (kg)" and unit == "mm"
    series = {name: (xs, ys) for name, xs, ys in lines}
    assert series["loading"][0] == [0.0, 5.0, 10.0] and series["unloading"][0] == [5.0, 0.0]
    np.testing.assert_allclose(series["loading"][1], [0.0, 0.05, 0.10], atol=1e-5)
    np.testing.assert_allclose(series["unloading"][1], [0.053, 0.003], atol=1e-5)


def test_a_procedure_without_its_own_plot_shows_the_miss_distance():
    sd = StepData("poses/000", "poses")
    sd.checks = [{"name": "miss P", "value": 0.02}, {"name": "miss P", "value": 0.03}]
    title, _, unit, lines = plot_series("some_new_procedure", [sd], stations())
    assert title.startswith("miss distance") and lines[0][2] == [0.02, 0.03]
