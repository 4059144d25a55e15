"""``robocal diagnose`` of an elastic 19-joint tree as a whole process (issue 24's speed target): a torso of three
joints, two 7-joint arms and a two-joint head, two targets per pose (of three: both hands, a point on the head),
500 poses, from the independent generator with joint elasticity (torso pitch, both shoulders) and lateral
elasticity (both elbows) under its own gravity, and 0.05 mm noise.

Printed beside baselines measured in the same run, interleaved: the same diagnosis of the rigid robot (the same
poses without elasticity: the candidate search with nothing to accept), and ``identify`` of the elastic data with
the right effects given (one fit).  Wall and CPU (user + system) of the whole process; the CPU figure is what a
loaded machine leaves alone.

    python benchmarks/bench_tree_diagnose.py [--repeat 3] [--poses 500]

Target: diagnose under 30 s on the 2-core development machine.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from benchmarks.bench_demo import child_env  # noqa: E402
from benchmarks.bench_tree import PAIRS, POINTS, interleaved, report, write_tree  # noqa: E402
from tests.fakes import tree_robot as tr  # noqa: E402

JOINT = {"torso_2_joint": 1.0e-5, "arm_left_2_joint": 4.0e-5, "arm_right_2_joint": 4.0e-5}
LATERAL = {"arm_left_4_joint": 6.0e-5, "arm_right_4_joint": 6.0e-5}
READINGS = ["torso_1_joint", "torso_2_joint"] + [f"arm_{s}_{k}_joint" for s in ("left", "right")
                                                 for k in range(1, 8)] + ["head_1_joint", "head_2_joint"]


def _files(tmp: Path, poses: int) -> dict[str, list[str]]:
    nominal, real = write_tree(tmp)
    elastic = tr.Elasticity(joint=JOINT, lateral=LATERAL)
    rng = np.random.default_rng(2)
    vals = tr.random_values(nominal, poses, 3, names=READINGS)
    with open(tmp / "elastic.csv", "w", newline="") as fe, open(tmp / "rigid.csv", "w", newline="") as fr:
        we, wr = csv.writer(fe), csv.writer(fr)
        for w in (we, wr):
            w.writerow(["pose", "target"] + READINGS + ["x", "y", "z"])
        for i, v in enumerate(vals):
            v["torso_3_joint"] = -(v["torso_1_joint"] + v["torso_2_joint"])
            for t in PAIRS[i % 3]:
                link, xyz = POINTS[t]
                noise = rng.normal(0, 0.05, 3)
                row = [f"p{i}", t] + [f"{np.degrees(v[k]):.8f}" for k in READINGS]
                we.writerow(row + [f"{x:.5f}" for x in tr.point_mm(real, v, link, xyz, elastic=elastic) + noise])
                wr.writerow(row + [f"{x:.5f}" for x in tr.point_mm(real, v, link, xyz) + noise])
    cli = [sys.executable, "-m", "app.cli"]
    robot = ["--robot", str(tmp / "tree.toml"), "--noise-mm", "0.05"]
    index = {name: k + 1 for k, name in enumerate(_joint_names(tmp / "tree.toml"))}
    effects = [a for name in JOINT for a in ("--effect", f"joint_compliance:{index[name]}")] + \
              [a for name in LATERAL for a in ("--effect", f"lateral_compliance:{index[name]}")]
    return {
        f"diagnose, 19-joint tree, elastic, 2 targets x {poses} poses":
            cli + ["diagnose", str(tmp / "elastic.csv")] + robot + ["--json"],
        "baseline: diagnose, the same poses of the rigid robot": cli + ["diagnose", str(tmp / "rigid.csv")] + robot,
        "baseline: identify, elastic, the right effects given": cli + ["identify", str(tmp / "elastic.csv")] + robot
        + effects,
    }


def _joint_names(description: Path) -> list[str]:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    code = "import sys; from calib.loading import load_robot; print('\\n'.join(load_robot(sys.argv[1]).joint_names))"
    out = subprocess.run([sys.executable, "-c", code, str(description)], capture_output=True, text=True, env=env)
    return out.stdout.split()


def _findings(cmd: list[str]) -> str:
    """The findings of the timed diagnosis (its run also fills the bytecode cache the timed runs use)."""
    env = child_env()
    doc = json.loads(subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT).stdout)
    found = ", ".join(f["label"] for f in doc["findings"]) or "none"
    return (f"findings: {found}; held-out RMS {doc['baseline_rms_mm']:.3f} -> {doc['final_rms_mm']:.4f} mm "
            f"(floor {doc['noise_floor_mm']:.4f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--poses", type=int, default=500)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        cmds = _files(Path(d), args.poses)
        first = next(iter(cmds.values()))
        print(_findings(first))
        times = interleaved(cmds, args.repeat)
    report(times, args.repeat)

if __name__ == "__main__":
    main()
