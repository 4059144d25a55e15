"""Provenance (contract C6): every identify, diagnose and reprocess output says which code, description, scenario and
command made it, in its JSON and its HTML report, next to the keys it always had."""
import hashlib
import json
import re
import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

from calib.provenance import command_line, provenance, provenance_html

KEYS = {"robocal_version", "git_commit", "robot_sha256", "scenario_sha256", "command_line"}
EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "demo-session.db"


def sha(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def shipped(name):
    return resources.files("calib") / "data" / name


def test_hashes_name_the_files_used(tmp_path):
    p = provenance(argv=["x", "identify", "a b.csv"])
    assert set(p) == KEYS
    assert p["robot_sha256"] == hashlib.sha256(shipped("puma560.toml").read_bytes()).hexdigest()
    assert p["scenario_sha256"] is None                              # no scenario involved
    assert p["command_line"] == "robocal identify 'a b.csv'"          # pasteable into a shell
    robot = tmp_path / "r.toml"
    robot.write_bytes(shipped("tiago_arm.toml").read_bytes() + b"\n# edited\n")
    q = provenance(robot, "default")
    assert q["robot_sha256"] == sha(robot) != p["robot_sha256"]
    assert q["scenario_sha256"] == hashlib.sha256(shipped("twin_default.toml").read_bytes()).hexdigest()
    # a description's own source string resolves to the shipped file it came from
    assert provenance("tiago_arm.toml")["robot_sha256"] == \
        hashlib.sha256(shipped("tiago_arm.toml").read_bytes()).hexdigest()
    commit = p["git_commit"]
    # a git checkout (where these tests run from) names its commit; an installed package without one says None
    if (Path(provenance.__code__.co_filename).resolve().parents[1] / ".git").exists():
        assert re.fullmatch(r"[0-9a-f]{40}(\+dirty)?", commit), commit
    else:
        assert commit is None
    html = provenance_html(q)
    assert "<footer>" in html and q["robot_sha256"] in html and provenance_html(None) == ""
    assert command_line([]) == "robocal"


def cli(*args):
    return subprocess.run([sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def poses_csv(tmp_path_factory):
    d = tmp_path_factory.mktemp("prov")
    csv = d / "poses.csv"
    r = cli("twin", "--poses", "60", "--export", str(csv))
    assert r.returncode == 0, r.stderr
    return csv


def test_identify_json_and_model_file_carry_provenance(poses_csv, tmp_path):
    out = tmp_path / "model.json"
    r = cli("identify", str(poses_csv), "--json", "--out", str(out))
    assert r.returncode == 0, r.stderr
    for doc in (json.loads(r.stdout), json.loads(out.read_text())):
        assert {"format", "parameters", "effects", "covariance", "residual_rms", "outliers"} <= set(doc)
        assert set(doc["provenance"]) == KEYS
        assert doc["provenance"]["command_line"].startswith("robocal identify ")
    r = cli("compensate", str(out), "10", "-40", "70", "30", "-20", "50", "--json")   # the file still loads
    assert r.returncode == 0, r.stderr


def test_diagnose_json_and_report_carry_provenance(poses_csv, tmp_path):
    rep = tmp_path / "rep"
    r = cli("diagnose", str(poses_csv), "--json", "--report", str(rep), "--robot", str(shipped("puma560.toml")))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert {"noise_floor_mm", "baseline_rms_mm", "findings"} <= set(out)
    assert out["provenance"]["robot_sha256"] == hashlib.sha256(shipped("puma560.toml").read_bytes()).hexdigest()
    assert json.loads((rep / "diagnosis.json").read_text())["provenance"] == out["provenance"]
    assert "Provenance" in (rep / "index.html").read_text()


def test_reprocess_json_and_report_carry_provenance(tmp_path):
    out, rep = tmp_path / "res.json", tmp_path / "rep"
    r = cli("reprocess", str(EXAMPLE), "--json", str(out), "--report", str(rep))
    assert r.returncode == 0, r.stderr
    prov = json.loads(out.read_text())["provenance"]
    assert KEYS <= set(prov) and {"code_version", "elapsed_s", "input_session"} <= set(prov)
    assert prov["scenario_sha256"] is not None                        # the example was recorded on the twin
    assert prov["robot_sha256"] in (rep / "report.html").read_text()
