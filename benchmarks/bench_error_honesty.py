"""Benchmark: are the stated errors honest?  Per Chapter 4 procedure, over seeded runs on independent data (the
thesis's formulas as plain numpy in tests/fakes/thesis_procedures.py; raw theodolite readings through the ruler fit and
the intersection, as reprocessing does), the median of |value - truth| / error and the share within 2 sigma.

An honest 1-sigma error gives a median near 0.67 and about 95 % within 2 sigma (target 0.55-0.85 and 90-99 %).
Baseline before the honest-errors work (robocal demo estimates): median 0.29, 99 % within 2 sigma.

    python benchmarks/bench_error_honesty.py              # 100 seeds per procedure (~5 min on one core)
    python benchmarks/bench_error_honesty.py --seeds 30   # quicker
"""
from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tests.est_honesty_runs import PROCEDURES, honesty  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100, help="seeded runs per procedure")
    ap.add_argument("--only", action="append", help="procedure name (repeatable); default all")
    args = ap.parse_args()
    print(f"{'procedure':24s} {'values':>7s} {'median |v-t|/err':>17s} {'within 2 sigma':>15s} {'s':>6s}")
    ok = True
    for name in args.only or PROCEDURES:
        t0 = time.perf_counter()
        h = honesty(name, range(args.seeds))
        good = 0.55 <= h["median_ratio"] <= 0.85 and 0.90 <= h["within_2sigma"] <= 0.99
        ok &= good
        print(f"{name:24s} {h['n']:7d} {h['median_ratio']:17.2f} {100 * h['within_2sigma']:14.1f}% "
              f"{time.perf_counter() - t0:6.1f}{'' if good else '  <- outside 0.55-0.85 / 90-99 %'}")
    print("target: median 0.55-0.85 (0.67 Gaussian), 90-99 % within 2 sigma; baseline (before): 0.29, 99 %")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
