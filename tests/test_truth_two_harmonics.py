"""The emulated truth of a transmission-error run whose twin has two harmonics: the run estimates the first
harmonic's amplitude, so its truth is ``hypot(s1, c1)`` of the scenario -- not a mix of the first and second
harmonics' sine coefficients (the bug of issue 25: the coefficients are stored s1, c1, s2, c2)."""
from __future__ import annotations

import math

from app.demo import build_demo, transmission_plan
from app.reprocess import reprocess

S1, C1, S2, C2 = 0.047, 0.020, 0.012, 0.009          # deg, written into the scenario below


def _scenario(tmp_path) -> str:
    from importlib import resources
    text = (resources.files("calib") / "data" / "twin_default.toml").read_text(encoding="utf-8")
    old = 'joint = 6\norder = 1.8\nsin_deg = [0.047]'
    assert old in text
    path = tmp_path / "two_harmonics.toml"
    path.write_text(text.replace(old, f"joint = 6\norder = 1.8\nsin_deg = [{S1}, {S2}]\ncos_deg = [{C1}, {C2}]"))
    return str(path)


def test_the_truth_of_a_two_harmonic_run_is_the_first_harmonic(tmp_path):
    plan = {"procedures": ["ruler", "sweeps", "transmission"], "ruler": {"repeats": 1},
            "sweeps": {"points": 5, "span_deg": 60.0, "joints": [6]},
            "transmission": transmission_plan([6], points=13, repeats=1), "seed": 2}
    d = build_demo(tmp_path / "te2.db", seed=2, plan=plan, scenario=_scenario(tmp_path))
    assert d.runner.run() == "finished"
    d.close()
    res = reprocess(str(tmp_path / "te2.db"))
    est = {e["name"]: e for e in res["estimates"]}
    amp = est["te.j6.amplitude1_rad"]
    assert math.isclose(amp["truth"], math.radians(math.hypot(S1, C1)), rel_tol=1e-9), amp
    assert math.isclose(est["te.j6.omega"]["truth"], 1.8)
