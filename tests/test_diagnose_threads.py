"""A diagnosis called from Python runs every BLAS on one thread, scipy's own OpenBLAS included if it loads.

Why: threadpoolctl caps only the BLAS libraries loaded when the cap starts; scipy ships its own OpenBLAS, which a
diagnosis may load lazily (a robust fit, a test with fractional degrees of freedom), so without care its fits ran
threaded (10 s of CPU instead of 1.7 for 400 poses on the 2-core machine).  The check runs in a fresh process (here
scipy is long loaded) with no thread variables set, and reads every loaded BLAS's thread count at each progress
report of the diagnosis; tests/test_cli_threads.py checks a scipy loaded inside the cap.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from calib import threads

_CODE = """
import json
from threadpoolctl import threadpool_info
from calib.diagnose.engine import diagnose
from sim.validate import Case, make_case_data
seen = {}
def progress(stage, frac):
    for p in threadpool_info():
        if p["user_api"] == "blas":
            seen[p["filepath"]] = max(seen.get(p["filepath"], 0), p["num_threads"])
data, _ = make_case_data(Case("transmission_error", 4, None, 3.0, seed=1, n_poses=60))
diagnose(data, level="full", progress=progress)
after = {p["filepath"]: p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}
print(json.dumps({"during": seen, "after": after}))
"""


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="more than one BLAS thread needs two cores")
def test_diagnose_runs_every_blas_on_one_thread():
    env = {k: v for k, v in os.environ.items() if k not in threads.BLAS_ENV_VARS + (threads.THREADS_ENV,)}
    r = subprocess.run([sys.executable, "-c", _CODE], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["during"], out
    assert set(out["during"].values()) == {1}, out
    assert max(out["after"].values()) > 1, out                        # the cap ends with the call (the check can fail)


def test_validation_workers_start_with_one_blas_thread(monkeypatch):
    """The pool spawns its workers at the first submit, not when it is built: the BLAS variables must still be set
    then (they were restored too early, and the workers ran the user's threading), and restored after."""
    import os

    from calib.diagnose.parallel import map_cases
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    assert map_cases(os.getenv, ["OPENBLAS_NUM_THREADS"] * 2, workers=2) == ["1", "1"]
    assert "OPENBLAS_NUM_THREADS" not in os.environ
