"""Diagnosis of a session database: the shipped demo session (emulated twin with the thesis's effects)."""
import json
import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "demo-session.db"


def test_diagnose_the_demo_session_names_the_twins_effects():
    before = EXAMPLE.read_bytes()
    r = subprocess.run([sys.executable, "-m", "app.cli", "diagnose", str(EXAMPLE), "--json"], capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    found = [(f["effect"], f["joint"]) for f in out["findings"]]
    # the twin carries compliance on joint 3 and transmission errors on joints 4 and 6 (thesis, section 5)
    assert ("joint_compliance", 3) in found and ("transmission_error", 4) in found
    assert out["final_rms_mm"] < out["baseline_rms_mm"]
    assert out["final_rms_mm"] < 1.3 * out["noise_floor_mm"]
    # the session's raw readings on both faces estimate the noise with no model (the twin reads to 3 arc seconds)
    ne = out["noise_estimate"]
    assert "both faces" in ne["from"] and not ne["upper_bound"]
    assert 1 / 1.5 < ne["estimated_mm"] / ne["given_mm"] < 1.5
    assert EXAMPLE.read_bytes() == before                   # read-only
