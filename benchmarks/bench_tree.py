"""Branched robots as whole processes (issue 23's speed targets): ``fk`` on a URDF, and ``identify`` of a 19-joint tree
(a torso of three joints, two 7-joint arms, a two-joint head) with two targets per pose, 500 poses.

Each figure is printed beside a plain baseline measured in the same run, interleaved:
* fk: the interpreter with numpy alone (the floor a Python command cannot go under) and, when installed, the import
  of yourdfpy, the URDF reader robocal used before (its trimesh/scipy chain was most of fk's 1.2-2.2 s);
* identify: the same command on one arm of the same robot (a 10-joint chain, one target per pose, 500 poses).

    python benchmarks/bench_tree.py [--repeat 5] [--poses 500]

Targets: fk under 0.5 s, identify under 5 s (whole process, wall) on the 2-core development machine.
"""
from __future__ import annotations

import argparse
import csv
import importlib.util
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from benchmarks.bench_demo import child_env  # noqa: E402
from tests.fakes import tree_robot as tr  # noqa: E402

PAIRS = (("L", "R"), ("L", "H"), ("R", "H"))
POINTS = {"L": ("hand_left_link", [0.0, 0.0, 30.0]), "R": ("hand_right_link", [10.0, 0.0, 30.0]),
          "H": ("head_2_link", [60.0, 0.0, 40.0])}


def write_tree(tmp: Path):
    """The generator's two-arm torso as ``robot.urdf`` and its calibration description ``tree.toml`` (the three
    points, the coupled torso joint); returns the nominal tree and the 'real' one the data come from."""
    nominal = tr.two_arm_torso(0)
    (tmp / "robot.urdf").write_text(tr.to_urdf(nominal))
    pts = "\n".join(f'{k} = {{ link = "{link}", xyz_mm = [{", ".join(map(str, xyz))}] }}'
                    for k, (link, xyz) in POINTS.items())
    coupled = "[joints.coupled]\ntorso_3_joint = { torso_1_joint = -1.0, torso_2_joint = -1.0 }\n"
    (tmp / "tree.toml").write_text(f'urdf = "robot.urdf"\nbase_link = "base_link"\n[tool.points]\n{pts}\n{coupled}')
    return nominal, tr.perturbed(nominal, 1)


def _files(tmp: Path, poses: int) -> dict[str, list[str]]:
    nominal, real = write_tree(tmp)
    (tmp / "arm.toml").write_text('urdf = "robot.urdf"\nbase_link = "base_link"\ntip_link = "hand_left_link"\n'
                                  '[tool.points]\nL = [0.0, 0.0, 30.0]\n')
    readings = ["torso_1_joint", "torso_2_joint"] + [f"arm_{s}_{k}_joint" for s in ("left", "right")
                                                     for k in range(1, 8)] + ["head_1_joint", "head_2_joint"]
    arm = ["torso_1_joint", "torso_2_joint", "torso_3_joint"] + [f"arm_left_{k}_joint" for k in range(1, 8)]
    rng = np.random.default_rng(2)
    vals = tr.random_values(nominal, poses, 3, names=readings)
    with open(tmp / "tree.csv", "w", newline="") as ft, open(tmp / "arm.csv", "w", newline="") as fa:
        wt, wa = csv.writer(ft), csv.writer(fa)
        wt.writerow(["pose", "target"] + readings + ["x", "y", "z"])
        wa.writerow(arm + ["x", "y", "z"])
        for i, v in enumerate(vals):
            v["torso_3_joint"] = -(v["torso_1_joint"] + v["torso_2_joint"])
            for t in PAIRS[i % 3]:
                link, xyz = POINTS[t]
                p = tr.point_mm(real, v, link, xyz) + rng.normal(0, 0.05, 3)
                wt.writerow([f"p{i}", t] + [f"{np.degrees(v[k]):.8f}" for k in readings] + [f"{x:.5f}" for x in p])
            p = tr.point_mm(real, v, *POINTS["L"]) + rng.normal(0, 0.05, 3)
            wa.writerow([f"{np.degrees(v[k]):.8f}" for k in arm] + [f"{x:.5f}" for x in p])
    cli = [sys.executable, "-m", "app.cli"]
    zeros = ["0"] * len(readings)
    out = {
        "fk, URDF (UR10)": cli + ["fk", "--robot", str(ROOT / "examples/urdf/ur10_robot.urdf")] + ["0"] * 6,
        "fk, the 19-joint tree": cli + ["fk", "--robot", str(tmp / "tree.toml")] + zeros,
        "baseline: python -c 'import numpy'": [sys.executable, "-c", "import numpy"],
        f"identify, 19-joint tree, 2 targets x {poses} poses": cli + ["identify", str(tmp / "tree.csv"), "--robot",
                                                                      str(tmp / "tree.toml"), "--noise-mm", "0.05"],
        f"baseline: identify, one 10-joint arm, {poses} poses": cli + ["identify", str(tmp / "arm.csv"), "--robot",
                                                                       str(tmp / "arm.toml"), "--noise-mm", "0.05"],
    }
    if importlib.util.find_spec("yourdfpy"):
        out["baseline: python -c 'import yourdfpy'"] = [sys.executable, "-c", "import yourdfpy"]
    return out


def _time(cmd: list[str]) -> tuple[float, float]:
    """(wall, CPU) seconds of the whole process; CPU (user + system) is what the machine's load leaves alone.
    Bytecode cached as an installed robocal has it, also where the environment sets ``PYTHONDONTWRITEBYTECODE``
    (the development machine does: every start compiled robocal from source, 0.4-0.5 s)."""
    env = child_env()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"failed: {' '.join(cmd)}\n{done.stderr}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--poses", type=int, default=500)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        cmds = _files(Path(d), args.poses)
        for k, cmd in cmds.items():             # warm the file cache once
            _time(cmd)
        times = interleaved(cmds, args.repeat)
    report(times, args.repeat)


def interleaved(cmds: dict[str, list[str]], repeat: int) -> dict[str, list[tuple[float, float]]]:
    """(wall, CPU) of every command ``repeat`` times, interleaved: the machine's load falls on every row alike."""
    times: dict[str, list[tuple[float, float]]] = {k: [] for k in cmds}
    for _ in range(repeat):
        for k, cmd in cmds.items():
            times[k].append(_time(cmd))
    return times


def report(times: dict[str, list[tuple[float, float]]], repeat: int) -> None:
    """The table: date, machine, load, then wall min/median/max and the median CPU of every command."""
    load = os.getloadavg()[0]
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, load {load:.1f}, "
          f"{repeat} runs each, whole process (s)")
    width = max(58, max(len(k) for k in times) + 2)
    print(f"  {'command':<{width}}{'wall min':>9}{'median':>8}{'max':>7}{'CPU median':>12}")
    for k, ts in times.items():
        w = [x for x, _ in ts]
        c = [y for _, y in ts]
        print(f"  {k:<{width}}{min(w):9.2f}{statistics.median(w):8.2f}{max(w):7.2f}{statistics.median(c):12.2f}")

if __name__ == "__main__":
    main()
