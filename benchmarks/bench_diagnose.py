"""Benchmark: one diagnosis of withheld-effect twin data (120 and 240 poses), on one core.

Prints the wall time of each stage budget: the geometric held-out fit, the effect selection, the whole run.
Run: ``python benchmarks/bench_diagnose.py``.
"""
from __future__ import annotations

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import time  # noqa: E402

from calib.diagnose.engine import diagnose  # noqa: E402
from calib.diagnose.validate import Case, make_case_data  # noqa: E402


def main() -> None:
    for n in (120, 240):
        data, desc = make_case_data(Case("transmission_error", 4, None, 3.0, seed=1, n_poses=n))
        diagnose(data, level="full", flag_outliers=False)              # warm-up (imports, caches)
        t0 = time.perf_counter()
        d = diagnose(data, level="full", flag_outliers=False)
        dt = time.perf_counter() - t0
        print(f"{n} poses: {dt:.2f} s for the diagnosis ({len(d.selection.rounds)} rounds, "
              f"{len(d.selection.findings)} finding(s): {[f.candidate.label for f in d.selection.findings]})")


if __name__ == "__main__":
    main()
