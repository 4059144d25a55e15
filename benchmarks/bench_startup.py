"""First contact: how long ``robocal --help`` (and a light command) takes as a whole process, next to a bare Python
start-up measured in the same run (the floor no CLI can beat).  Target: ``robocal --help`` under 150 ms.

    python benchmarks/bench_startup.py [--runs 10]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time


def wall_ms(cmd: list[str], runs: int) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    runs = ap.parse_args().runs
    rows = [("python -c pass (floor)", [sys.executable, "-c", "pass"]),
            ("robocal --help", [sys.executable, "-m", "acq.cli", "--help"]),
            ("robocal fk --help", [sys.executable, "-m", "acq.cli", "fk", "--help"]),
            ("robocal fk 0 -90 90 0 0 0", [sys.executable, "-m", "acq.cli", "fk", "0", "-90", "90", "0", "0", "0"])]
    print(f"{'command':<28}{'median wall (ms)':>18}   ({runs} runs)")
    for name, cmd in rows:
        print(f"{name:<28}{wall_ms(cmd, runs):>18.0f}")


if __name__ == "__main__":
    main()
