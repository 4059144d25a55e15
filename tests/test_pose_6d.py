"""6-D pose rows (rx_deg, ry_deg, rz_deg beside x, y, z) end to end, on data from an independently built UR10 (a
perturbed URDF multiplied out as plain 4x4 products, tests/fakes/urdf_chain.py): the model files are valid, rows
count as poses, the convention and noise are stated, orientation errors are geodesic, diagnose says it drops them."""
import csv
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from calib.compensate import load_model
from tests.fakes.urdf_chain import UrdfChain, perturbed, rpy_matrix

UR10 = Path(__file__).resolve().parents[1] / "examples" / "urdf" / "ur10_robot.urdf"
JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint"]
NOISE_DEG = 0.001


def _euler_xyz(R: np.ndarray) -> np.ndarray:
    """(rx, ry, rz) deg with R = Rz(rz) Ry(ry) Rx(rx), written out here from the matrix (not robocal's)."""
    return np.degrees([np.arctan2(R[2, 1], R[2, 2]), -np.arcsin(R[2, 0]), np.arctan2(R[1, 0], R[0, 0])])


def _small_rotation(rng, sigma_rad):
    w = rng.normal(0, sigma_rad, 3)
    a = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / max(a, 1e-300)
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


@pytest.fixture(scope="module")
def six(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("six")
    truth = UrdfChain(perturbed(UR10.read_text(), seed=8, mm=2.0, deg=0.3), "world", "wrist_3_link")
    rng = np.random.default_rng(31)
    q = rng.uniform(-2.8, 2.8, (40, 6))
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rpy_matrix(0.02, -0.01, 2.9), [1600.0, 500.0, -200.0]
    F = T @ truth.tip_frames(q)
    path = tmp / "six.csv"
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(JOINTS + ["x", "y", "z", "rx_deg", "ry_deg", "rz_deg", "split"])
        for i, (qi, Fi) in enumerate(zip(q, F)):
            p = Fi[:3, 3] + rng.normal(0, 0.01, 3)
            e = _euler_xyz(Fi[:3, :3] @ _small_rotation(rng, np.radians(NOISE_DEG)))
            e[2] += 360.0 if (i % 2 and e[2] < 0) else (-360.0 if i % 2 else 0.0)   # the same frame, rz a turn away
            w.writerow([f"{v:.10f}" for v in np.degrees(qi)] + [f"{v:.6f}" for v in p] + [f"{v:.9f}" for v in e]
                       + ["fit" if i < 28 else "test"])
    return tmp, path


def _run(capsys, argv):
    rc = main(argv)
    out = capsys.readouterr()
    assert rc == 0, out.err
    return out


def test_six_d_rows_end_to_end(six, capsys):
    tmp, data = six
    model, robot_toml = tmp / "m.json", tmp / "r.toml"
    common = [str(data), "--robot", str(UR10), "--noise-mm", "0.01", "--orientation-noise-deg", str(NOISE_DEG)]
    text = _run(capsys, ["identify", *common, "--out", str(model), "--out-robot", str(robot_toml)]).out
    # rows are poses, the convention and the noise are stated
    assert text.startswith(f"robocal identify {data}: accuracy on ") and "\n  28 poses," in text
    assert ("orientation: rx_deg..rz_deg: the measured frame in the instrument frame, R = Rz(rz) Ry(ry) Rx(rx); "
            "1 sigma 0.001 deg per axis") in text
    doc = json.loads(_run(capsys, ["identify", *common, "--json"]).out)
    assert doc["n_poses"] == 28 and doc["n_fit"] == 28 and doc["n_test"] == 12
    o = doc["orientation"]
    assert o["noise_deg"] == NOISE_DEG and "R = Rz(rz) Ry(ry) Rx(rx)" in o["convention"]
    # geodesic errors: half the rows carry rz a whole turn away, which an rpy difference would call 360 deg
    assert o["fit"]["n"] == 28 and o["fit"]["max_deg"] < 0.01
    assert o["test"]["n"] == 12 and o["test"]["max_deg"] < 0.01 and o["test"]["mean_deg"] > 0.0
    # the files are valid TOML / JSON and load; evaluate scores positions and orientations of the test rows
    tomllib.loads(robot_toml.read_text())
    tomllib.loads(json.loads(model.read_text())["robot_toml"])
    assert "wrist_3_link@x" in load_model(model).model.robot.tool_points_mm
    ev = json.loads(_run(capsys, ["evaluate", str(model), str(data), "--json"]).out)
    assert ev["n"] == 12 and ev["rms_mm"] < 0.05
    assert ev["orientation"]["n"] == 12 and ev["orientation"]["max_deg"] < 0.01
    assert ev["orientation"]["max_deg"] == pytest.approx(o["test"]["max_deg"], rel=1e-9)
    text = _run(capsys, ["evaluate", str(model), str(data)]).out
    assert "orientation (rx_deg..rz_deg: the measured frame in the instrument frame, R = Rz(rz) Ry(ry) Rx(rx)): " \
           "geodesic error mean" in text


def test_a_wrong_orientation_is_seen_as_an_angle(six, capsys, tmp_path):
    """The geodesic error is the angle: one test row turned by 2 deg about its x axis reads 2 deg."""
    tmp, data = six
    model = tmp / "m.json"
    if not model.exists():
        _run(capsys, ["identify", str(data), "--robot", str(UR10), "--noise-mm", "0.01", "--orientation-noise-deg",
                      str(NOISE_DEG), "--out", str(model)])
    lines = data.read_text().splitlines()
    cols = lines[0].split(",")
    row = lines[-1].split(",")
    e = [float(row[cols.index(c)]) for c in ("rx_deg", "ry_deg", "rz_deg")]
    R = rpy_matrix(*np.radians(e)) @ rpy_matrix(np.radians(2.0), 0.0, 0.0)
    for c, v in zip(("rx_deg", "ry_deg", "rz_deg"), _euler_xyz(R)):
        row[cols.index(c)] = f"{v:.9f}"
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines[:-1] + [",".join(row)]) + "\n")
    ev = json.loads(_run(capsys, ["evaluate", str(model), str(bad), "--json"]).out)
    assert ev["orientation"]["max_deg"] == pytest.approx(2.0, abs=0.01)


def test_diagnose_says_it_drops_the_orientations(six, capsys):
    tmp, data = six
    doc = json.loads(_run(capsys, ["diagnose", str(data), "--robot", str(UR10), "--noise-mm", "0.01", "--json",
                                   "--max-effects", "0"]).out)
    assert f"{data}: rx_deg, ry_deg, rz_deg dropped: the diagnosis compares positions only (identify and evaluate " \
           "use the orientations)" in doc["notes"]
