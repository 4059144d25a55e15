"""A session keeps the robot it was recorded with, a URDF's chain cut included, and every later reader (reprocess,
diagnose, export) loads that chain from the session's set-up."""
from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from tests.dev_extra import require

from app.cli import main
from calib.errors import RobocalError
from calib.loading import RobotPath

UR10 = str(Path(__file__).resolve().parents[1] / "examples" / "urdf" / "ur10_robot.urdf")
NAMES = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
THEODOLITES = ["A=geocom:robocal://geocom?seed=3&station=A", "B=gsi:robocal://gsi?seed=3&station=B"]


def _stored_setup(db) -> dict:
    return json.loads(sqlite3.connect(db).execute("SELECT setup_json FROM session").fetchone()[0])


def test_session_records_the_chain_cut_and_reloads_it(tmp_path):
    from app.commands.session import real_builder, setup_template
    from offline.exchange import session_robot
    (tmp_path / "setup.json").write_text(json.dumps(setup_template()))
    db = str(tmp_path / "s.db")
    build = real_builder(db, THEODOLITES, None, str(tmp_path / "setup.json"), None,
                         RobotPath(UR10, "base_link", None), ["ruler/p0"])
    build(None).close()
    setup = _stored_setup(db)
    assert setup["robot"] == UR10 and setup["base_link"] == "base_link" and "tip_link" not in setup
    robot = session_robot(db)
    # the default cut starts at the URDF's root (world), 0.9 m below base_link: a different chain
    assert robot.name.endswith("(base_link -> wrist_3_link)")
    # resuming: with the same robot or none, fine; with another cut, one line naming the recorded one
    real_builder(db, THEODOLITES, None, None, None, None, ["ruler/p0"])
    real_builder(db, THEODOLITES, None, None, None, RobotPath(UR10, "base_link", None), ["ruler/p0"])
    with pytest.raises(RobocalError, match=r"recorded with the robot .*ur10_robot.urdf \(chain cut base_link -> -\)"):
        real_builder(db, THEODOLITES, None, None, None, RobotPath(UR10), ["ruler/p0"])


def test_reprocess_of_an_imported_session_uses_the_setups_cut(tmp_path):
    """Points of wrist_3_link in base_link's frame, computed by Pinocchio (an independent implementation), imported
    with a set-up naming the UR10 cut at base_link: reprocess identifies that chain (its robot document names the
    cut) and fits the points to their noise."""
    pin = require("pinocchio", "pin")
    from app.reprocess import reprocess
    from acq.session.setup import standard_setup
    model = pin.buildModelFromUrdf(UR10)
    data = model.createData()
    base, tip = model.getFrameId("base_link"), model.getFrameId("wrist_3_link")
    rng = np.random.default_rng(4)
    q = rng.uniform(-2.0, 2.0, (40, 6))
    lines = [",".join(NAMES + ["x", "y", "z", "sigma_x_mm", "sigma_y_mm", "sigma_z_mm"])]
    for row in q:
        qq = pin.neutral(model)
        for name, v in zip(NAMES, row):
            qq[model.joints[model.getJointId(name)].idx_q] = v
        pin.framesForwardKinematics(model, data, qq)
        M = data.oMf[base].inverse() * data.oMf[tip]
        p = M.translation * 1000.0 + rng.normal(0, 0.01, 3)
        lines.append(",".join([f"{v:.9f}" for v in np.degrees(row)] + [f"{v:.6f}" for v in p] + ["0.01"] * 3))
    (tmp_path / "p.csv").write_text("\n".join(lines) + "\n")
    setup = {**standard_setup(), "robot": UR10, "base_link": "base_link", "base_xyz_mm": [0.0, 0.0, 0.0]}
    setup.pop("compliance"), setup.pop("link")
    (tmp_path / "setup.json").write_text(json.dumps(setup))
    assert main(["import", str(tmp_path / "p.csv"), "--db", str(tmp_path / "i.db"), "--setup",
                 str(tmp_path / "setup.json")]) == 0
    res = reprocess(str(tmp_path / "i.db"))
    assert "(base_link -> wrist_3_link)" in res["robot"]["nominal_robot_toml"]
    assert res["figures"]["poses"]["rms_mm"] < 0.05
