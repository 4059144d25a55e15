"""Approach directions from the measurement order (issue 27, item 1) and the bad input around it."""
from __future__ import annotations

import numpy as np
import pytest

from app.cli import main
from calib.approach import last_moves
from calib.posecsv import read_pose_csv
from calib.units import DEG

from .fakes.backlash_sessions import Arm, Play, approach_of, sessions, write_csv


def test_last_move_above_the_threshold_sets_the_side_and_the_first_pose_has_none():
    q = np.array([[0.0, 0.0], [10.0, 0.0], [10.2, 5.0], [4.0, 5.0], [4.0, 5.3]]) * DEG
    d = last_moves(q, [False, False], threshold_rad=0.5 * DEG)
    # joint 1: +10 deg, a 0.2 deg creep (below the threshold: the side stays), -6.2 deg, no move
    assert d[:, 0].tolist() == [0, 1, 1, -1, -1]
    # joint 2: still, +5 deg, then nothing, then 0.3 deg (below)
    assert d[:, 1].tolist() == [0, 0, 1, 1, 1]


def test_a_prismatic_joint_uses_its_length_threshold():
    q = np.array([[0.0, 0.0], [0.4, 0.004], [1.4, 0.004]])     # mm, rad
    d = last_moves(q, [True, False], threshold_rad=0.5 * DEG, threshold_mm=0.5)
    assert d[:, 0].tolist() == [0, 0, 1] and d[:, 1].tolist() == [0, 0, 0]


def test_the_inferred_directions_are_the_generators_after_the_first_pose(tmp_path):
    """The generator's own directions come from its motion sequence (it knows where the first pose came from);
    the file's order gives the same signs on every later pose."""
    s = sessions(Arm([Play(3, 0.1 * DEG)]), n_program=30, n_sessions=1, seed=3)[0]
    p = write_csv(tmp_path / "s.csv", s)
    t = read_pose_csv(p, 6, order="auto")
    assert "time column time" in t.direction_note and t.direction.shape == (30, 6)
    assert np.array_equal(t.direction[1:], s.approach[1:]) and not t.direction[0].any()
    # the placebo (the NEXT move) agrees with the truth no better than chance
    nxt = approach_of(s.q_rad, s.q_rad[0], next_move=True)
    assert np.mean(nxt[1:-1] == s.approach[1:-1]) < 0.75


def _csv(tmp_path, name: str, header: str, rows: list[str]):
    p = tmp_path / name
    p.write_text("\n".join([header] + rows) + "\n")
    return p


ROWS = [f"{i * 10},{-90 + i},{90 - i},0,{i},0,{500 + i},{i},{100 + i},{t}" for i, t in
        enumerate([5.0, 6.0, 7.5, 9.0])]


def test_time_like_column_rows_order_and_dir_columns(tmp_path):
    hdr = "q1,q2,q3,q4,q5,q6,x,y,z,t_start_robot"
    t = read_pose_csv(_csv(tmp_path, "a.csv", hdr, ROWS), 6, order="auto")
    assert "t_start_robot" in t.direction_note and "t_start_robot" not in t.ignored_columns
    assert t.time_s is not None and t.direction[1:, 0].tolist() == [1, 1, 1]
    plain = [",".join(r.split(",")[:-1]) for r in ROWS]
    u = read_pose_csv(_csv(tmp_path, "b.csv", hdr.rsplit(",", 1)[0], plain), 6, order="auto")
    assert u.direction is None          # no time column: the rows are not assumed to be in measurement order
    v = read_pose_csv(_csv(tmp_path, "b.csv", hdr.rsplit(",", 1)[0], plain), 6, order="rows")
    assert "row order" in v.direction_note and v.direction[1:, 1].tolist() == [1, 1, 1]
    given = [r + ",-1,1,1,1,1,1" for r in plain]
    w = read_pose_csv(_csv(tmp_path, "c.csv", hdr.rsplit(",", 1)[0] + ",dir1,dir2,dir3,dir4,dir5,dir6", given), 6,
                      order="auto")
    assert w.direction_note == "" and (w.direction[:, 0] == -1).all()       # the file's own columns win


def _one_line(capsys, *needles):
    err = capsys.readouterr().err.strip()
    lines = [ln for ln in err.splitlines() if ln.startswith("robocal: error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def test_bad_time_input_is_one_line_exit_2(tmp_path, capsys):
    hdr = "q1,q2,q3,q4,q5,q6,x,y,z,time"
    back = ROWS[:2] + [ROWS[3], ROWS[2]]
    p = _csv(tmp_path, "back.csv", hdr, back)
    assert main(["diagnose", str(p), "--noise-mm", "0.1"]) == 2
    _one_line(capsys, str(p), "line 5", "column time", "must not go back")
    ok = _csv(tmp_path, "ok.csv", hdr, ROWS)
    assert main(["diagnose", str(ok), "--noise-mm", "0.1", "--time-column", "stamp"]) == 2
    _one_line(capsys, str(ok), "--time-column stamp", "no such column")
    plain = _csv(tmp_path, "plain.csv", hdr.rsplit(",", 1)[0], [",".join(r.split(",")[:-1]) for r in ROWS])
    assert main(["diagnose", str(plain), "--noise-mm", "0.1", "--order", "time"]) == 2
    _one_line(capsys, str(plain), "--order time", "no time column")


def test_a_confirmation_file_with_bad_time_or_another_robots_joints_is_refused(tmp_path, capsys):
    hdr = "q1,q2,q3,q4,q5,q6,x,y,z,time"
    data = write_csv(tmp_path / "data.csv", sessions(Arm(), n_program=30, n_sessions=1, seed=4)[0])
    back = _csv(tmp_path, "back.csv", hdr, ROWS[:2] + [ROWS[3], ROWS[2]])
    assert main(["diagnose", str(data), "--noise-mm", "0.1", "--confirm", str(back)]) == 2
    _one_line(capsys, str(back), "must not go back")


URDF = "examples/urdf/tiago_no_hand.urdf"


@pytest.fixture
def tiago_toml(tmp_path):
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    p = tmp_path / "tiago.toml"
    p.write_text(f'urdf = "{root / URDF}"\nbase_link = "base_footprint"\ntip_link = "arm_7_link"\n'
                 f'[tool.points]\n1 = [0.0, 0.0, 0.0]\n')
    return p


def test_a_confirmation_file_with_other_joint_names_is_refused(tmp_path, capsys, tiago_toml):
    names = ["torso_lift_joint"] + [f"arm_{k}_joint" for k in range(1, 8)]
    rng = np.random.default_rng(0)
    rows = [",".join(["0.2"] + [f"{v:.4f}" for v in rng.uniform(-1, 1, 7)] + [f"{v:.4f}" for v in rng.uniform(0, 1, 3)]
                     + [f"{i}"]) for i in range(30)]
    data = _csv(tmp_path, "data.csv", ",".join(names) + ",x1,y1,z1,time", rows)
    ur = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint", "a_joint", "b_joint"]
    other = _csv(tmp_path, "ur.csv", ",".join(ur) + ",x1,y1,z1,time", rows)
    argv = ["diagnose", str(data), "--robot", str(tiago_toml), "--noise-mm", "0.1", "--angle-unit", "rad",
            "--length-unit", "m", "--confirm", str(other)]
    assert main(argv) == 2
    _one_line(capsys, str(other), "shoulder_pan_joint", "is not a joint of the description")
