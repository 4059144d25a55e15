"""The twin: reproducible truth from the one model, the thesis's defaults, and clear scenario errors."""
import json
import subprocess
import sys
from importlib import resources

import numpy as np
import pytest

from calib.errors import ConfigError
from calib.theodolite import intersect
from sim.twin import Twin, load_scenario, parse_scenario
from calib.units import ARCSEC, DEG, NM_PER_LBIN
from tests.fakes import thesis_puma as fake
from tests.fakes.thesis_puma import ThesisPuma, base_matrix

DEFAULT = (resources.files("calib") / "data" / "twin_default.toml").read_text()


def test_default_scenario_follows_the_thesis():
    sc = load_scenario()
    eff = {e.label: e for e in sc.effects}
    te4, te6 = eff["transmission_error.j4"], eff["transmission_error.j6"]
    assert te4.order == 0.9 and te4.values[0] == pytest.approx(0.050 * DEG)
    assert te6.order == 1.8 and te6.values[0] == pytest.approx(0.047 * DEG)
    k3 = eff["joint_compliance.j3"]
    assert 1 / k3.values[0] == pytest.approx(1.156e5 * NM_PER_LBIN, rel=1e-6)
    assert 1 / k3.values[1] == pytest.approx(1.223e5 * NM_PER_LBIN, rel=1e-6)
    assert k3.values[2] == pytest.approx(100 * NM_PER_LBIN, rel=1e-6)
    k4 = eff["joint_compliance.j4"]
    assert 1 / k4.values[0] == pytest.approx(2.275e5 * NM_PER_LBIN, rel=1e-6)
    assert sc.stations[0].sigma_hz_rad == pytest.approx(3 * ARCSEC)
    assert sc.stations[1].x_mm == pytest.approx(1609.9)
    assert set(sc.disabled) == {"backlash.j2", "link_compliance.j2", "thermal_drift"}


def test_same_seed_same_measurements_different_seed_different_noise():
    q = np.array([[0.1, -1.2, 1.4, 0.3, 0.5, -0.2]] * 4)
    m1 = Twin().measure(q)
    m2 = Twin().measure(q)
    m3 = Twin(seed=7).measure(q)
    np.testing.assert_array_equal(m1.readings_rad, m2.readings_rad)
    assert not np.allclose(m1.readings_rad, m3.readings_rad)
    np.testing.assert_array_equal(m1.point_true_mm, m3.point_true_mm)


def test_encoder_counts_are_integers_and_quantise_the_readings():
    tw = Twin()
    q = tw.random_poses(50)
    m = tw.measure(q)
    assert m.counts.dtype == np.int64
    step = 2 * np.pi / (np.abs(tw.robot.gear_ratio) * tw.robot.counts_per_rev)
    err = np.abs(m.q_read_rad - q)
    assert np.all(err <= 1.5 * step + 1e-12)             # coupling mixes the wrist joints' half counts
    assert np.any(err > 1e-9)


def thesis_arm(tw: Twin) -> ThesisPuma:
    """The independent generator set to the twin's true geometry (masses from the description file itself)."""
    t = tw.true_parameters()
    arm = ThesisPuma.from_toml(resources.files("calib") / "data" / "puma560.toml")
    for j in range(6):
        for attr, key in (("alpha", "alpha_rad"), ("a_mm", "a_mm"), ("d_mm", "d_mm"),
                          ("theta_offset", "theta_offset_rad"), ("beta", "beta_rad")):
            getattr(arm, attr)[j] = t[f"j{j + 1}.{key}"]
    arm.base = base_matrix([t["base.x_mm"], t["base.y_mm"], t["base.z_mm"]], t["base.yaw_rad"],
                           t["base.pitch_rad"], t["base.roll_rad"])
    arm.tool_xyz_t = (-t["tool.x_mm"], -t["tool.y_mm"], -t["tool.z_mm"])      # ^6E puts the tool at -Xt, -Yt, -Zt
    return arm


def thesis_running_errors(tw: Twin) -> list:
    t = tw.true_parameters()
    c = {j: (1 / t[f"joint_compliance.j{j}.compliance1_rad_per_nm"], 1 / t[f"joint_compliance.j{j}.compliance2_rad_per_nm"],
             t[f"joint_compliance.j{j}.breakpoint_nm"]) for j in (3, 4)}
    return [fake.TransmissionError(4, 0.9, t["transmission_error.j4.s1_rad"]),
            fake.TransmissionError(6, 1.8, t["transmission_error.j6.s1_rad"]),
            fake.JointCompliance(3, *c[3]), fake.JointCompliance(4, *c[4]),
            fake.CrossCoupling(6, 5, t["cross_coupling.j5j6.sigma"])]


def test_twin_truth_agrees_with_the_independent_thesis_generator():
    """True tool points and joint angles of the default twin (geometry, base, tool, transmission errors, two-slope
    compliance under gravity and payload, coupling) against plain A-matrix products of the thesis."""
    tw = Twin()
    q = tw.random_poses(60)
    payload = np.where(np.arange(60) % 3 == 0, 6.0, 0.0)
    m = tw.measure(q, tw.context(60, payload_kg=payload))
    arm = thesis_arm(tw)
    pts, th = fake.true_points(arm, m.q_read_rad, thesis_running_errors(tw), payload)
    np.testing.assert_allclose(m.point_true_mm, pts, atol=1e-9, rtol=0)
    np.testing.assert_allclose(m.theta_true_rad, th, atol=1e-12, rtol=0)
    rigid, _ = fake.true_points(arm, m.q_read_rad)
    assert np.abs(m.point_true_mm - rigid).max() > 0.1          # the running errors are there to be compared


def test_twin_readings_agree_with_the_thesis_station_formulas():
    """Noise-free readings: eq 4.3.1's inverse (section 5.3.1) with the offsets gamma1, gamma2 of the scenario."""
    sc = parse_scenario(DEFAULT.replace("angles = true", "angles = false").replace("height_b_mm = 0.0",
                                                                                   "height_b_mm = 120.0"))
    tw = Twin(sc)
    m = tw.measure(tw.random_poses(80))
    expect = fake.leica_readings(m.point_true_mm, 1609.9, -1.489 * DEG, 1.358 * DEG, 120.0)
    np.testing.assert_allclose(np.angle(np.exp(1j * (m.readings_rad - expect))), 0.0, atol=1e-12)
    alpha, beta, phi_a, _ = fake.thesis_angles(m.point_true_mm, 1609.9, 120.0)
    np.testing.assert_allclose(fake.point_from_angles(alpha, beta, phi_a, 1609.9), m.point_true_mm, atol=1e-9)


def test_readings_intersect_back_to_the_truth_within_noise():
    tw = Twin()
    q = tw.random_poses(300)
    m = tw.measure(q)
    out = intersect(tw.stations, [(m.readings_rad[:, 0], m.readings_rad[:, 1]),
                                  (m.readings_rad[:, 2], m.readings_rad[:, 3])])
    z = (out.point_mm - m.point_true_mm) / out.sigma_mm
    assert 0.8 < np.std(z) < 1.2                        # the stated covariance is honest


def test_noise_free_twin_is_exact():
    sc = parse_scenario(DEFAULT.replace("angles = true", "angles = false"))
    tw = Twin(sc)
    m = tw.measure(tw.random_poses(10))
    out = intersect(tw.stations, [(m.readings_rad[:, 0], m.readings_rad[:, 1]),
                                  (m.readings_rad[:, 2], m.readings_rad[:, 3])])
    np.testing.assert_allclose(out.point_mm, m.point_true_mm, atol=1e-9)


def test_observe_draws_the_station_noise_from_the_given_stream():
    """Twin.observe is the one place reading noise is drawn: any station subset and face, the caller's generator."""
    tw = Twin()
    quiet = Twin(parse_scenario(DEFAULT.replace("angles = true", "angles = false")))
    p = tw.true_points(tw.random_poses(2000))[0]
    state = tw.rng.bit_generator.state
    out, gross = tw.observe(p, [tw.stations[1]], [2], rng=np.random.default_rng(3))
    assert tw.rng.bit_generator.state == state                  # an emulator keeps its own stream
    assert out.shape == gross.shape == (2000, 2) and not gross.any()
    again, _ = tw.observe(p, [tw.stations[1]], [2], rng=np.random.default_rng(3))
    np.testing.assert_array_equal(out, again)
    exact, _ = quiet.observe(p, [quiet.stations[1]], [2])
    d = np.angle(np.exp(1j * (out - exact)))                    # Hz wraps at 2 pi
    z = d / [tw.stations[1].sigma_hz_rad, tw.stations[1].sigma_v_rad]
    assert np.all(np.abs(z.mean(0)) < 0.1) and np.all(np.abs(z.std(0) - 1) < 0.06)
    assert np.all((out[:, 0] >= 0) & (out[:, 0] < 2 * np.pi))
    # sight is observe from every station with the twin's own generator
    np.testing.assert_array_equal(Twin().sight(p[:5])[0], Twin().observe(p[:5])[0])


@pytest.mark.parametrize("angles, rate", [(True, 0.0), (True, 0.3), (False, 0.3)])
def test_one_reading_is_the_array_codes_reading(angles, rate):
    """An emulated theodolite's one reading at a time (the plain-float path) is bit for bit what the array
    expression below -- the noise, gross errors and Hz wrap of Twin.noisy for many points -- gives with the same
    generator, draw for draw (the generators end in the same state)."""
    text = DEFAULT.replace("gross_rate = 0.0", f"gross_rate = {rate}")
    tw = Twin(parse_scenario(text if angles else text.replace("angles = true", "angles = false")))
    st = [tw.stations[0], tw.stations[1]]
    exact = tw.exact_readings(tw.true_points(tw.random_poses(200))[0], st, [1, 2])
    mine, ref = np.random.default_rng(11), np.random.default_rng(11)
    for row in exact:
        got, gross = tw.noisy(row[None], st, rng=mine)
        sig = np.array([v for s in st for v in (s.sigma_hz_rad, s.sigma_v_rad)])
        want = row[None] + ref.normal(size=(1, 4)) * sig if angles else row[None].copy()
        g = ref.random((1, 4)) < rate
        if g.any():
            want = want + g * ref.choice([-1.0, 1.0], (1, 4)) * tw.scenario.gross_rad
        want[:, 0::2] = np.mod(want[:, 0::2], 2 * np.pi)
        assert got.tobytes() == want.tobytes() and np.array_equal(gross, g)
    assert mine.bit_generator.state == ref.bit_generator.state


def test_one_points_exact_readings_are_the_arrays():
    tw = Twin()
    pts = tw.true_points(tw.random_poses(50))[0]
    for p in pts:
        for st in tw.stations:
            for face in (1, 2):
                assert tw.exact_one(p, st, face) == tw.exact_readings(p[None], [st], [face])[0].tolist()


def test_gross_errors_are_injected_at_the_stated_rate():
    sc = parse_scenario(DEFAULT.replace("gross_rate = 0.0", "gross_rate = 0.1"))
    tw = Twin(sc)
    m = tw.measure(tw.random_poses(1000))
    assert 0.07 < m.gross.mean() < 0.13


def test_switching_an_effect_off_removes_its_signature():
    on = Twin()
    off = Twin(parse_scenario(DEFAULT.replace('order = 0.9\nsin_deg = [0.050]',
                                              'order = 0.9\nsin_deg = [0.050]\nenabled = false')))
    q = on.random_poses(30)
    d = on.true_points(q)[1] - off.true_points(q)[1]
    np.testing.assert_allclose(d[:, 3], 0.050 * DEG * np.sin(0.9 * q[:, 3]), atol=1e-9)


@pytest.mark.parametrize("old,new,key,words", [
    ('type = "backlash"', 'type = "friction"', "effect[6].type", "unknown kind 'friction'"),
    ("joint = 4\norder = 0.9", "joint = 9\norder = 0.9", "effect[1].joint", "1..6"),
    ('"j3.a_mm" = -29.7', '"j3.length_mm" = -29.7', "geometry.set.j3.length_mm", "unknown parameter"),
    ("sigma_arcsec = 3.0", "sigma_arcsec = -3.0", "stations.sigma_arcsec", "positive"),
    ("stiffness_nm_per_rad = 13061.04288", "stiffness_nm_per_rad = nan", "effect[3].stiffness_nm_per_rad",
     "finite"),
    ("seed = 1986", "seed = 1986\nspeed = 3", "twin.speed", "unknown key"),
])
def test_bad_scenario_names_file_and_key(tmp_path, old, new, key, words):
    assert old in DEFAULT
    f = tmp_path / "scen.toml"
    f.write_text(DEFAULT.replace(old, new, 1))
    with pytest.raises(ConfigError) as exc:
        load_scenario(f)
    msg = str(exc.value)
    assert "scen.toml" in msg and key in msg and words in msg


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=120)


def test_twin_command_json_summary():
    r = run_cli("twin", "--poses", "60", "--json")
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    gap = {g["what"]: g for g in s["gap"]}
    # the thesis's Fig 5.10 deviations (a2 -29.7 vs -20.3 mm ...) dominate the uncalibrated gap
    assert gap["geometry alone (DH deviations)"]["rms_mm"] > 5.0
    assert 0.01 < gap["transmission_error.j4 alone"]["max_mm"] < 1.0
    assert gap["joint_compliance.j3 alone"]["rms_mm"] > gap["cross_coupling.j5j6 alone"]["rms_mm"]
    assert all(0.005 < v < 0.5 for v in s["instrument"]["point_sigma_median_mm"])


def test_fk_command_json_on_default_robot():
    """robocal fk on the description without a tool: the origin of frame 6 from the thesis's A-matrices."""
    r = run_cli("fk", "10", "-70", "95", "20", "-30", "40", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert set(out) == {"x_mm", "y_mm", "z_mm"}
    expect = ThesisPuma().tool_point(np.array([10, -70, 95, 20, -30, 40]) * DEG)
    np.testing.assert_allclose([out["x_mm"], out["y_mm"], out["z_mm"]], expect, atol=1e-6)


@pytest.mark.parametrize("args,words", [
    (["fk", "0", "0", "0"], "expected 6 joint readings"),
    (["fk", "0", "0", "x", "0", "0", "0"], "joint 3 reading 'x' is not a number"),
    (["fk", "0", "0", "nan", "0", "0", "0"], "not finite"),
    (["twin", "--scenario", "/no/such.toml"], "/no/such.toml: file not found"),
])
def test_cli_bad_input_is_one_line(args, words):
    r = run_cli(*args)
    assert r.returncode == 2
    assert words in r.stderr and "Traceback" not in r.stderr
