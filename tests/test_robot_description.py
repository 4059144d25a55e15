"""The robot description file: the shipped Puma 560, the encoder model, and clear errors on bad files."""
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from calib.errors import ConfigError
from calib.robot import parse_robot, robot_to_toml
from calib.loading import load_robot
from calib.units import DEG

from importlib import resources

PUMA_TEXT = (resources.files("calib") / "data" / "puma560.toml").read_text()


def test_default_is_the_thesis_puma(puma):
    # Fig 3.5 link table and Fig 5.10 "specified" column
    np.testing.assert_allclose(puma.alpha_rad / DEG, [-90, 180, 90, -90, 90, 0])
    np.testing.assert_allclose(puma.a_mm, [0, 432.0, -20.3, 0, 0, 0])
    np.testing.assert_allclose(puma.d_mm, [0, 149.1, 0, 432.0, 0, 57.1])
    assert puma.hayati.tolist() == [False, True, False, False, False, False]
    # published gear ratios (Corke & Armstrong-Helouvry) and the thesis's wrist coupling
    np.testing.assert_allclose(puma.gear_ratio, [-62.6111, 107.815, -53.7063, 76.0364, 71.923, 76.686])
    assert puma.coupling[4, 3] == 0.0139 and puma.coupling[5, 3] == 0.0131 and puma.coupling[5, 4] == 0.1802
    assert puma.tool_points_mm == {}
    np.testing.assert_allclose(puma.tool_point(), 0.0)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-4.0, 4.0), min_size=6, max_size=6))
def test_joint_to_counts_round_trip(q):
    robot = load_robot()
    q = np.array(q)
    np.testing.assert_allclose(robot.joint_from_counts(robot.counts_from_joint(q)), q, atol=1e-12)


def test_coupling_moves_the_wrist_motors(puma):
    """10 deg of joint 5 alone turns motor 6 by sigma56 x 10 deg (times its gear ratio)."""
    q = np.zeros(6)
    q[4] = 10 * DEG
    m = puma.motor_angles_rad(q)
    assert m[5] / puma.gear_ratio[5] / DEG == pytest.approx(0.1802 * 10)
    assert m[4] / puma.gear_ratio[4] / DEG == pytest.approx(10)


def test_counts_per_degree_match_protocols_table(puma):
    # protocols.md §5.2: joint 1 173.920 counts/deg, joint 2 (800 CPR) 239.589 counts/deg
    per_deg = np.abs(puma.gear_ratio) * puma.counts_per_rev / 360
    assert per_deg[0] == pytest.approx(173.920, abs=1e-3)
    assert per_deg[1] == pytest.approx(239.589, abs=1e-3)


def test_write_and_read_back(puma):
    again = parse_robot(robot_to_toml(puma.with_tool({"P": [1.0, 2.0, 3.0]})))
    for field in ("a_mm", "d_mm", "alpha_rad", "gear_ratio", "counts_per_rev", "mass_kg", "com_mm", "coupling",
                  "limits_rad"):
        np.testing.assert_allclose(getattr(again, field), getattr(puma, field))
    np.testing.assert_allclose(again.tool_point("P"), [1, 2, 3])


@pytest.mark.parametrize("old,new,key,words", [
    ("gear_ratio = 107.815", "", "joint[2].gear_ratio", "missing"),
    ("encoder_counts_per_rev = 800", "encoder_counts_per_rev = -800", "joint[2].encoder_counts_per_rev",
     "positive"),
    ("a_mm = 432.0", "a_mm = nan", "joint[2].a_mm", "finite"),
    ("mass_kg = 17.4", "mass_kg = -17.4", "joint[2].mass_kg", ">= 0"),
    ("hayati = true", "hayati = true\nlength_mm = 3", "joint[2].length_mm", "unknown key"),
    ("sigma56 = 0.1802", "sigma56 = 0.1802\nmatrix = [[1.0]]", "coupling", "not both"),
    ("limits_deg = [-225.0, 45.0]", "limits_deg = [45.0, -225.0]", "joint[2].limits_deg", "below"),
    ("limits_deg = [-225.0, 45.0]", "limits_mm = [0.0, 350.0]", "joint[2].limits_deg", "missing"),
    ("name = \"waist\"", "name = \"waist\"\ntype = \"linear\"", "joint[1].type", "revolute or prismatic"),
    ("a_mm = 432.0", 'a_mm = "long"', "joint[2].a_mm", "number"),
])
def test_bad_robot_file_names_file_and_key(tmp_path, old, new, key, words):
    assert old in PUMA_TEXT
    bad = tmp_path / "bad_robot.toml"
    bad.write_text(PUMA_TEXT.replace(old, new, 1))
    with pytest.raises(ConfigError) as exc:
        load_robot(bad)
    msg = str(exc.value)
    assert "bad_robot.toml" in msg and key in msg and words in msg
    assert "\n" not in msg


def test_singular_coupling_matrix_is_refused(tmp_path):
    text = PUMA_TEXT.replace("sigma45 = 0.0139\nsigma46 = 0.0131\nsigma56 = 0.1802",
                             "matrix = " + str([[0.0] * 6] * 6))
    bad = tmp_path / "r.toml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match="singular"):
        load_robot(bad)


def test_cli_reports_bad_file_in_one_line_without_traceback(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text(PUMA_TEXT.replace("d_mm = 57.1", "d_mm = nan"))
    r = subprocess.run([sys.executable, "-m", "app.cli", "fk", "0", "0", "0", "0", "0", "0", "--robot", str(bad)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0
    assert "broken.toml: joint[6].d_mm: must be a finite number" in r.stderr
    assert "Traceback" not in r.stderr


def test_invalid_toml_syntax(tmp_path):
    bad = tmp_path / "syntax.toml"
    bad.write_text("[robot\nname=1")
    with pytest.raises(ConfigError, match="syntax.toml: not valid TOML"):
        load_robot(bad)
