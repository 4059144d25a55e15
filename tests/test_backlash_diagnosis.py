"""Withheld play found from the measurement order and confirmed on other sessions (issue 27, item 5).

Truth from tests/fakes/backlash_sessions.py (its own chain, gravity torque, play and motion sequence; nothing from
calib): three sessions of one 60-pose program on a Puma, each in its own order, from its own instrument set-up.  The
files carry no directions, only a time column: robocal infers them.  Cases: plain play; play that gravity holds
with a lumped end-effector mass the description does not know; play on the shoulder that gravity hides in most of
the workspace; the placebo (each row's NEXT move as its direction); no play at all; and play the other sessions do
not have (left out of the exported model).
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from calib.units import DEG

from .fakes.backlash_sessions import Arm, Play, sessions, write_csv

PLAY = ("backlash", "backlash_gravity")
CASES = {
    "plain_j3": (Arm([Play(3, 0.08 * DEG)]), "backlash", 3, 0.08),
    "gravity_j5_tool_mass": (Arm([Play(5, 0.3 * DEG, 1.0)], tool_mass_kg=2.0), "backlash_gravity", 5, 0.3),
    # the shoulder's torque exceeds the preload in most poses: there the play sits on gravity's side, an offset
    "hidden_j2": (Arm([Play(2, 0.05 * DEG, 15.0)]), "backlash_gravity", 2, 0.05),
    "clean": (Arm([]), None, None, None),
}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    out = {}
    for name, (arm, *_) in CASES.items():
        d = tmp_path_factory.mktemp(name)
        out[name] = [write_csv(d / f"s{i}.csv", s) for i, s in enumerate(sessions(arm, 60, 3, seed=0))]
    return out


def _diagnose(capsys, data, others, *extra):
    argv = ["diagnose", str(data), "--json", *extra] + [a for o in others for a in ("--confirm", str(o))]
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("case", ["plain_j3", "gravity_j5_tool_mass", "hidden_j2"])
def test_withheld_play_is_named_confirmed_and_agrees(case, files, capsys):
    _, kind, joint, width_deg = CASES[case]
    j = _diagnose(capsys, files[case][0], files[case][1:])
    assert any("approach directions inferred from the time column time" in n for n in j["notes"])
    plays = [f for f in j["findings"] if f["effect"] in PLAY]
    assert len(plays) == 1, [f["label"] for f in j["findings"]]
    f = plays[0]
    assert (f["effect"], f["joint"]) == (kind, joint), f["label"]
    w, s = f["parameters"]["width_deg"], f["parameters"]["width_sigma_deg"]
    assert abs(w - width_deg) < max(3 * s, 0.1 * width_deg), (w, s, width_deg)
    k = j["findings"].index(f)
    for c in j["confirmation"]:
        g = c["findings"][k]
        assert g["confirmed"] and g["kind"] == kind and g["joint_name"]
        assert g["refit"]["agree"], g["refit"]
        assert c["final_rms_mm"] < 0.6 * c["geometric_rms_mm"]
    assert j["exported_model"]["findings"] == [x["label"] for x in j["findings"]]


def test_placebo_the_next_move_finds_no_play(files, capsys, tmp_path):
    """The same sessions with each row's direction of the NEXT move written as dir columns: no play is named."""
    import csv

    from .fakes.backlash_sessions import approach_of
    src = files["plain_j3"][0]
    rows = list(csv.reader(open(src)))
    q = np.array([[float(v) for v in r[:6]] for r in rows[1:]]) * DEG
    nxt = approach_of(q, q[0], next_move=True)
    p = tmp_path / "placebo.csv"
    with open(p, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(rows[0] + [f"dir{j}" for j in range(1, 7)])
        w.writerows([r + [f"{v:g}" for v in d] for r, d in zip(rows[1:], nxt)])
    j = _diagnose(capsys, p, [])
    assert not any("inferred" in n for n in j["notes"])
    assert not [f["label"] for f in j["findings"] if f["effect"] in PLAY]


def test_no_play_no_finding(files, capsys):
    j = _diagnose(capsys, files["clean"][0], [])
    assert not [f["label"] for f in j["findings"] if f["effect"] in PLAY]


def test_play_the_other_sessions_lack_is_left_out_of_the_exported_model(files, capsys, tmp_path):
    """Session 1 of the plain-play arm against two sessions of the same program on a repaired arm: the play is found
    on the data, confirmed on neither session, and the model written by --out carries no play."""
    from calib.compensate import load_model
    out = tmp_path / "model.json"
    j = _diagnose(capsys, files["plain_j3"][0], files["clean"][1:], "--out", str(out))
    k = next(i for i, f in enumerate(j["findings"]) if f["effect"] in PLAY)
    assert j["findings"][k]["confirmed"] is False
    assert all(not c["findings"][k]["confirmed"] for c in j["confirmation"])
    assert j["findings"][k]["label"] in j["exported_model"]["left_out"]
    im = load_model(out)
    assert not [e for e in im.model.effects if e.kind in PLAY]


def test_the_stated_width_error_is_honest_over_seeds(tmp_path):
    """|width - truth| / sigma over 12 seeded sessions (gravity-held play on joint 5 with its preload and tool mass
    given, directions inferred from the time column, full geometry fitted alongside): median near 0.67.  Measured
    0.39: the first pose's side is known to the robot (it came from home) but not to the data, and that one pose's
    misfit inflates sigma through the reduced chi-square (identify's rule) -- conservative, not optimistic."""
    from calib.diagnose.data import load_data
    from calib.effects import make_effect
    from calib.identify import default_free, identify
    from calib.loading import load_robot

    z = []
    for seed in range(12):
        s = sessions(Arm([Play(5, 0.3 * DEG, 1.0)], tool_mass_kg=2.0), 40, 1, seed=seed)[0]
        d = load_data(write_csv(tmp_path / f"s{seed}.csv", s), load_robot(), order="auto")
        m = d.model([make_effect("backlash_gravity", 5, preload_nm=1.0, tool_mass_kg=2.0)])
        th = m.nominal.copy()
        th[m.index["tool.z_mm"]] = 120.0
        name = "backlash_gravity.j5.width_rad"
        idn = identify(m, d.observations(), free=default_free(m, effects=False) + [name], theta0=th, outliers="off")
        z.append((idn.theta[m.index[name]] - 0.3 * DEG) / idn.sigma[m.index[name]])
    assert 0.3 < np.median(np.abs(z)) < 1.0, np.round(z, 2)
