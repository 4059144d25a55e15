"""Joint names from the description wherever a person reads, and every printed parameter name accepted back
(calib/names.py, the one naming module)."""
import json
import re
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from calib import names
from calib.loading import load_robot

EX = Path(__file__).resolve().parents[1] / "examples"
TIAGO = [str(EX / "tiago" / "qualysis_base_hand_calibration.csv"), "--robot", str(EX / "tiago" / "tiago_mocap.toml"),
         "--angle-unit", "rad", "--length-unit", "m", "--noise-mm", "1"]
#: a joint said by its number where a name exists: "joint 7", "joints 1", "j7", "q7" (not dir1.., not x1..)
NUMBERED = re.compile(r"\b[Jj]oints? \d|(?<![\w.])[jq]\d+\b")


@pytest.fixture(scope="module")
def tiago():
    return load_robot(str(EX / "tiago" / "tiago_mocap.toml"))


def _run(capsys, argv):
    rc = main(argv)
    out = capsys.readouterr()
    assert rc == 0, out.err
    return out.out


def test_display_and_back(tiago):
    assert names.joint_names(tiago)[6] == "arm_6_joint"
    assert names.display("j7.a_mm", tiago) == "arm_6_joint.a_mm"
    assert names.edge("j7.alpha_rad", np.pi / 2, 0.01, tiago) == ("arm_6_joint.alpha_deg", 90.0, pytest.approx(
        np.degrees(0.01)), "deg")
    assert names.display("joint_compliance.j3@2.compliance_rad_per_nm", tiago) == \
        "joint_compliance.arm_2_joint@2.compliance_rad_per_nm"
    known = {"j7.alpha_rad", "j3.a_mm", "base.z_mm"}
    for typed, want in (("arm_6_joint.alpha_deg", ("j7.alpha_rad", np.pi / 180)), ("j7.alpha_rad", ("j7.alpha_rad", 1.0)),
                        ("arm_2_joint.a_mm", ("j3.a_mm", 1.0)), ("base.z_mm", ("base.z_mm", 1.0))):
        name, scale = names.internal(typed, tiago, known)
        assert (name, scale) == (want[0], pytest.approx(want[1]))
    # a prismatic joint's zero offset is its d, in mm; its theta turns the next link
    assert names.zero_offset_parameter(tiago, 1) == "j1.d_mm" and names.joint_value_unit(tiago, 1) == "mm"
    from calib.identifiability import describe
    assert describe("j1.d_mm", tiago) == "torso_lift_joint zero offset (torso_lift_joint.d_mm)"
    assert describe("j1.theta_offset_rad", tiago) == \
        "torso_lift_joint turn about its axis (torso_lift_joint.theta_offset_deg)"


def test_a_robot_without_one_word_names_keeps_numbers():
    """The thesis's Puma names its joints "wrist roll": its outputs keep j1..j6 and the thesis's words."""
    puma = load_robot()
    assert names.joint_names(puma) == tuple(f"j{k}" for k in range(1, 7)) and not names.named(puma)
    assert names.prose("joint 3 angle, j3.a_mm", puma) == "joint 3 angle, j3.a_mm"
    from calib.identifiability import describe
    assert describe("j2.a_mm", puma) == "upper arm a1 (j2.a_mm)"
    dh_named = load_robot(str(Path(__file__).resolve().parents[1] / "calib" / "data" / "tiago_arm.toml"))
    assert names.named(dh_named) and names.joint_label(dh_named, 7) == "arm_6_joint"


def test_identify_says_names_and_takes_every_printed_name_back(capsys):
    text = _run(capsys, ["identify", *TIAGO])
    body = "\n".join(text.splitlines()[1:])                       # the first line names the data file
    assert not NUMBERED.search(body), NUMBERED.search(body)
    assert "arm_6_joint.alpha_deg" in body and "torso_lift_joint turn about its axis" in body
    table = text.split("unit\n", 1)[1].splitlines()
    printed = [ln.split()[0] for ln in table if ln.startswith("  ") and len(ln.split()) == 4]
    printed += re.findall(r"\(([A-Za-z_][\w.@]*)\)", body)        # the identifiability sentences' names
    held = next(ln for ln in body.splitlines() if "held at their design values" in ln)
    printed += held.split(": ", 1)[1].split(", ")
    assert len(printed) > 40 and any(p.endswith("_deg") for p in printed)
    # every one is accepted by --free (one run: all of them)
    _run(capsys, ["identify", *TIAGO, "--free", ",".join(sorted(set(printed)))])
    doc = json.loads(_run(capsys, ["identify", *TIAGO, "--free", "base.*,tool.*,arm_6_joint.*", "--select", "all",
                                   "--json"]))
    p = {x["name"]: x for x in doc["parameters"]}
    assert p["j7.a_mm"]["joint"] == 7 and p["j7.a_mm"]["joint_name"] == "arm_6_joint"
    assert "joint" not in p["base.z_mm"]
    assert {x["name"] for x in doc["parameters"] if x["estimated"]} >= {"j7.a_mm", "j7.alpha_rad", "base.z_mm"}
    assert not any(x["estimated"] for x in doc["parameters"] if x["name"].startswith("j6."))


def test_effect_by_joint_name(capsys):
    doc = json.loads(_run(capsys, ["identify", *TIAGO, "--effect", "joint_compliance:arm_2_joint", "--json"]))
    assert {"type": "joint_compliance", "joint": 3} == {k: doc["effects"][0][k] for k in ("type", "joint")}
    rc = main(["identify", *TIAGO, "--effect", "joint_compliance:elbow"])
    err = [ln for ln in capsys.readouterr().err.splitlines() if "warning" not in ln]
    assert rc == 2 and len(err) == 1 and "'elbow' is not a joint of the robot (joints: torso_lift_joint" in err[0]


def test_diagnose_names_joints(capsys):
    args = [*TIAGO[:1], *TIAGO[1:-1], "0.2", "--max-effects", "1"]
    text = _run(capsys, ["diagnose", *args])
    body = "\n".join(ln for ln in text.splitlines()[1:] if "dir1" not in ln)
    assert not NUMBERED.search(body), NUMBERED.search(body)
    assert "torso_lift_joint position" in body and "arm_6_joint angle" in body
    doc = json.loads(_run(capsys, ["diagnose", *args, "--json"]))
    for f in doc["findings"]:
        assert names.joint_names(load_robot(str(EX / "tiago" / "tiago_mocap.toml")))[f["joint"] - 1] == \
            f["joint_name"]


def test_a_parameter_key_reads_as_words_and_unit():
    """A finding's parameters are printed as a quantity and its unit (``width 1.7 deg``), not as a JSON key."""
    assert names.quantity_words("width_deg") == ("width", "deg")
    assert names.quantity_words("preload_nm") == ("preload", "N m")
    assert names.quantity_words("tool_mass_kg") == ("tool mass", "kg")
    assert names.quantity_words("compliance1_rad_per_nm") == ("compliance1", "rad/(N m)")
    assert names.quantity_words("sigma") == ("sigma", "")
