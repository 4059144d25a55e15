"""Start-up: how long the ``robocal`` command takes as a whole process before it does any work, next to a bare Python
start-up measured in the same run (the floor no command can beat), and what share of real commands start-up is.

Targets (issue 18, the 2-core development machine, whole process, median): ``robocal --help`` <= 150 ms,
``robocal fk 0 -90 90 0 0 0`` <= 350 ms.  The commands are run interleaved (one of each per round), so a change of
the machine's load hits them alike; the load average is printed before and after.

Start-up share of real commands: each runs in a fresh process that calls ``app.cli.main`` twice; the second call
finds every module imported, so its time is the command's own work (``compute``), and ``start-up`` is the process's
wall time minus that (interpreter, imports, first-call set-up).  Cases: ``robocal reprocess`` of the example
session, ``robocal identify`` and ``robocal diagnose`` of 400 poses of the twin (``robocal twin --poses 400
--export``, written before the clock starts).

Bytecode: the children run with Python's bytecode cache on (in a folder under the temporary directory, so nothing
is written into the tree), as an installed package has it, also where the environment sets
PYTHONDONTWRITEBYTECODE (the development machine does: every robocal module would be compiled from source on every
start, 0.1-0.3 s); a first, untimed round fills the cache.

    python benchmarks/bench_startup.py [--runs 10] [--share-runs 3] [--only start|share]
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROBOCAL = [sys.executable, "-m", "app.cli"]
FK = ["fk", "0", "-90", "90", "0", "0", "0"]
#: (row, argv after the interpreter, target ms or None)
START_ROWS = [("python -c pass (floor)", ["-c", "pass"], None),
              ("robocal --help", ["-m", "app.cli", "--help"], 150.0),
              ("robocal fk --help", ["-m", "app.cli", "fk", "--help"], None),
              ("robocal fk 0 -90 90 0 0 0", ["-m", "app.cli", *FK], 350.0)]

#: the child for the share rows: two calls of main(); prints the second call's time (s)
SHARE_CHILD = """
import contextlib, io, os, sys, time
from app.cli import main
argv = sys.argv[1:]
with contextlib.redirect_stdout(io.StringIO()):
    assert main(argv) == 0
    t = time.perf_counter()
    assert main(argv) == 0
print(time.perf_counter() - t)
"""


def _env() -> dict[str, str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
               PYTHONPYCACHEPREFIX=str(Path(tempfile.gettempdir()) / "robocal-bench-pycache"))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _load() -> str:
    return "load average %.2f %.2f %.2f" % os.getloadavg()


def _wall_ms(argv: list[str], env: dict[str, str]) -> float:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, *argv], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    ms = (time.perf_counter() - t0) * 1e3
    if r.returncode:
        sys.exit(f"bench_startup: {' '.join(argv)} failed: {r.stderr.decode(errors='replace').strip()}")
    return ms


def start_rows(runs: int) -> None:
    env = _env()
    for _, argv, _ in START_ROWS:               # warm the file cache once, untimed
        _wall_ms(argv, env)
    times: dict[str, list[float]] = {name: [] for name, _, _ in START_ROWS}
    for _ in range(runs):
        for name, argv, _ in START_ROWS:
            times[name].append(_wall_ms(argv, env))
    floor = statistics.median(times[START_ROWS[0][0]])
    print(f"{'command (whole process)':<28}{'median ms':>10}{'min ms':>8}{'over floor':>12}{'target ms':>11}  verdict")
    for name, _, target in START_ROWS:
        med = statistics.median(times[name])
        verdict = "" if target is None else ("PASS" if med <= target else "FAIL")
        print(f"{name:<28}{med:>10.0f}{min(times[name]):>8.0f}{med - floor:>12.0f}"
              f"{'' if target is None else f'{target:.0f}':>11}  {verdict}")


def _share_cases(tmp: Path) -> list[tuple[str, list[str]]]:
    db = tmp / "demo-session.db"
    shutil.copy(ROOT / "examples" / "demo-session.db", db)     # reprocess is read-only; a copy all the same
    csv = tmp / "twin400.csv"
    subprocess.run([*ROBOCAL, "twin", "--poses", "400", "--seed", "0", "--export", str(csv)], env=_env(),
                   stdout=subprocess.DEVNULL, check=True)
    return [("robocal reprocess examples/demo-session.db", ["reprocess", str(db), "--json", str(tmp / "r.json")]),
            ("robocal identify (400 poses)", ["identify", str(csv), "--json"]),
            ("robocal diagnose (400 poses)", ["diagnose", str(csv), "--json"])]


def share_rows(runs: int) -> None:
    env = _env()
    with tempfile.TemporaryDirectory() as tmp:
        cases = _share_cases(Path(tmp))
        walls: dict[str, list[float]] = {n: [] for n, _ in cases}
        computes: dict[str, list[float]] = {n: [] for n, _ in cases}
        for round_ in range(runs + 1):           # round 0 fills the bytecode cache, untimed
            for name, argv in cases:
                # the child calls main() twice: the process's wall time would count the work twice, so the first
                # call's share is wall minus one compute
                t0 = time.perf_counter()
                r = subprocess.run([sys.executable, "-c", SHARE_CHILD, *argv], capture_output=True, text=True,
                                   env=env)
                wall = time.perf_counter() - t0
                if r.returncode:
                    sys.exit(f"bench_startup: {name} failed: {r.stderr.strip()[-500:]}")
                compute = float(r.stdout.strip().splitlines()[-1])
                if not round_:
                    continue
                walls[name].append(wall - compute)
                computes[name].append(compute)
    print(f"\n{'command (one run, whole process)':<44}{'wall s':>8}{'compute s':>11}{'start-up s':>12}{'share':>7}")
    for name, _ in cases:
        wall, compute = statistics.median(walls[name]), statistics.median(computes[name])
        print(f"{name:<44}{wall:>8.2f}{compute:>11.2f}{wall - compute:>12.2f}{(wall - compute) / wall:>7.0%}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10, help="rounds of the start-up rows (default 10)")
    ap.add_argument("--share-runs", type=int, default=3, help="rounds of the start-up share rows (default 3)")
    ap.add_argument("--only", choices=("start", "share"), help="only one of the two tables")
    a = ap.parse_args()
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} CPUs, {_load()}")
    if a.only != "share":
        start_rows(a.runs)
    if a.only != "start":
        share_rows(a.share_runs)
    print(_load())


if __name__ == "__main__":
    main()
