"""The identified model as files, and compensation with it."""
import json
import subprocess
import sys

import numpy as np
import pytest

from calib.compensate import (compensate_command, corrected_readings, load_model, nominal_in_same_frame, predict,
                              save_model)
from calib.effects import effect_from_text
from calib.errors import RobocalError
from calib.identify import PointObservations, identify
from calib.model import MeasurementModel
from calib.loading import load_robot
from calib.theodolite import intersect
from sim.twin import Twin


@pytest.fixture(scope="module")
def identified(tmp_path_factory):
    tw = Twin(seed=21)
    n = 200
    q = tw.random_poses(n)
    ctx = tw.context(n, payload_kg=np.where(np.arange(n) % 2 == 0, 0.0, 5.0))
    m = tw.measure(q, ctx)
    pts = intersect(tw.stations, [(m.readings_rad[:, 0], m.readings_rad[:, 1]),
                                  (m.readings_rad[:, 2], m.readings_rad[:, 3])])
    model = MeasurementModel(tw.robot, [effect_from_text(s) for s in
                                        ("transmission_error:4:0.9", "transmission_error:6:1.8", "joint_compliance:3",
                                         "cross_coupling:6:5")])
    res = identify(model, PointObservations(m.q_read_rad, pts.point_mm, pts.cov_mm2, ctx=ctx))
    d = tmp_path_factory.mktemp("model")
    path = d / "model.json"
    save_model(path, model, res, d / "robot.toml", truth=tw.true_parameters())
    return tw, model, res, path, d


def test_model_file_round_trip(identified):
    tw, model, res, path, d = identified
    im = load_model(path)
    q = tw.random_poses(20)
    np.testing.assert_allclose(im.model.points(q, theta=im.theta), model.points(q, theta=res.theta), atol=1e-9)
    doc = json.loads(path.read_text())
    entry = {p["name"]: p for p in doc["parameters"]}["transmission_error.j4.s1_rad"]
    assert entry["unit"] == "rad" and entry["estimated"] and entry["error"] > 0 and entry["truth"] is not None
    # the identified robot description is a valid robot file with the identified geometry
    robot = load_robot(d / "robot.toml")
    assert robot.a_mm[1] == pytest.approx(res.value("j2.a_mm"))


def test_corrected_readings_recover_true_joint_angles(identified):
    tw, model, res, path, _ = identified
    im = load_model(path)
    q = tw.random_poses(50)
    true = tw.true_points(q)[1]
    corrected = corrected_readings(im, q)
    # the corrections follow the truth's running errors on joints 4 and 6 to a small fraction of their size
    for j in (3, 5):
        assert np.sqrt(np.mean((corrected[:, j] - true[:, j]) ** 2)) < 0.25 * np.sqrt(np.mean((q[:, j] - true[:, j]) ** 2))


def test_compensated_commands_reach_the_intended_points(identified):
    tw, model, res, path, _ = identified
    im = load_model(path)
    nominal = nominal_in_same_frame(im)
    q = tw.random_poses(30)
    intended = nominal.points(q)
    before = np.linalg.norm(tw.true_points(q)[0] - intended, axis=1)
    cmd, resid = compensate_command(im, nominal, q)
    after = np.linalg.norm(tw.true_points(cmd)[0] - intended, axis=1)
    assert np.all(resid < 1e-4)
    assert np.sqrt(np.mean(after ** 2)) < 0.1 < np.sqrt(np.mean(before ** 2))
    p, s = predict(im, cmd)
    assert np.all(s > 0) and np.all(s < 0.1)


def test_bad_model_file(tmp_path):
    f = tmp_path / "m.json"
    f.write_text('{"format": "something else"}')
    with pytest.raises(RobocalError, match="not a robocal model file"):
        load_model(f)
    f.write_text("{not json")
    with pytest.raises(RobocalError, match="line 1, column 2: not valid JSON"):
        load_model(f)


def test_identify_and_compensate_commands(tmp_path):
    csv = tmp_path / "poses.csv"
    run = lambda *a: subprocess.run([sys.executable, "-m", "app.cli", *a], capture_output=True, text=True,
                                    timeout=300)
    r = run("twin", "--poses", "120", "--export", str(csv))
    assert r.returncode == 0, r.stderr
    model = tmp_path / "model.json"
    r = run("identify", str(csv), "--thesis-effects", "--out", str(model), "--out-robot", str(tmp_path / "r.toml"))
    assert r.returncode == 0, r.stderr
    assert "held at their design values" in r.stdout and "transmission_error.j4.s1_deg" in r.stdout
    r = run("compensate", str(model), "10", "-40", "70", "30", "-20", "50", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert len(out["command_deg"]) == 6 and out["residual_mm"] < 1e-3
    r = run("identify", str(tmp_path / "missing.csv"))
    assert r.returncode == 2 and "file not found" in r.stderr
    r = run("identify", str(csv), "--effect", "friction:2")
    assert r.returncode == 2 and "unknown kind 'friction'" in r.stderr
