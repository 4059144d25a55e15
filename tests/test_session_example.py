"""The shipped example session (examples/demo-session.db, made by ``robocal demo``) reprocesses read-only to estimates
that agree with the twin's truth within their stated errors, with gauge-held parameters flagged instead of compared."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from app.reprocess import reprocess

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
DB = EXAMPLES / "demo-session.db"
K_SIGMA = 4.0          # estimates within this many stated 1-sigma errors of the truth


@pytest.fixture(scope="module")
def result():
    if not DB.exists():
        pytest.fail(f"{DB} is missing: regenerate it as examples/README.md says")
    before = hashlib.sha256(DB.read_bytes()).hexdigest()
    mtime = DB.stat().st_mtime_ns
    side = [Path(str(DB) + s) for s in ("-wal", "-shm", "-journal")]
    existed = {p: p.exists() for p in side}
    res = reprocess(str(DB))
    assert hashlib.sha256(DB.read_bytes()).hexdigest() == before, "reprocessing modified the example session"
    assert DB.stat().st_mtime_ns == mtime
    assert [p for p in side if p.exists() and not existed[p]] == [], "reprocessing left SQLite side files"
    return res


def test_example_reprocesses_without_problems(result):
    assert result["problems"] == []
    assert result["session"]["exit_status"] == "success"
    shipped = json.loads((EXAMPLES / "demo-session.json").read_text())
    assert shipped["session"]["guid"] == result["session"]["guid"]          # the JSON was made from this file
    # reprocessing today gives the estimates the shipped JSON holds
    assert {e["name"] for e in shipped["estimates"]} == {e["name"] for e in result["estimates"]}


def test_example_recovers_the_stiffnesses(result):
    """Issue 12: the demo (``robocal demo --seed 0`` at commit bf3b37d, this file) recovers K3 and K4 of the twin within 3 of their
    stated errors, each error under 30 % of its value -- joint 4 loaded where its axis is horizontal."""
    est = {e["name"]: e for e in result["estimates"]}
    for n in ("compliance.j3.K1_Nm_per_rad", "compliance.j4.K1_Nm_per_rad"):
        e = est[n]
        assert e["truth"] is not None and abs(e["value"] - e["truth"]) <= 3.0 * e["error"], e
        assert e["error"] < 0.3 * e["value"], e


def test_example_estimates_agree_with_the_truth(result):
    est = result["estimates"]
    compared = [e for e in est if e["truth"] is not None and e["error"] > 0 and not e["held"]]
    # every stage is represented, the pose set with its running errors
    # (no "link.": the example's gauges were recorded before the bench took bending from the scenario, whose link
    # compliance is switched off, so they have no truth)
    for prefix in ("ruler.", "dh.", "ident.", "te.", "compliance.", "coupling.", "ident.transmission_error"):
        assert any(e["name"].startswith(prefix) for e in compared), prefix
    bad = [(e["name"], e["value"], e["truth"], e["error"]) for e in compared
           if abs(e["value"] - e["truth"]) > K_SIGMA * e["error"]]
    assert not bad, bad


def test_example_held_parameters_are_flagged_not_compared(result):
    held = [e for e in result["estimates"] if e["held"]]
    assert held, "the Puma's pose set cannot determine every parameter: some must be held"
    for e in held:
        assert e["error"] == 0.0 and "held" in e["note"], e
    # the free parameters that absorb a held one are compared in its gauge, with the raw truth kept alongside
    yaw = next(e for e in result["estimates"] if e["name"] == "ident.base.yaw_rad")
    assert "truth_raw" in yaw and abs(yaw["value"] - yaw["truth"]) <= K_SIGMA * yaw["error"]
    assert abs(yaw["value"] - yaw["truth_raw"]) > K_SIGMA * yaw["error"]
