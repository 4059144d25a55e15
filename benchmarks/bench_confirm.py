"""Benchmark: a diagnosis confirmed over several sessions (issue 27), whole process.

The real case of the issue: the TIAGo training session (37 poses, four hand points each) diagnosed and confirmed on
the three other sessions (62, 63 and 59 poses) of shared/data/figaroh-tiago-extra, ``robocal diagnose TRAINING
--confirm A --confirm B --confirm C``, with approach directions inferred from the t_start_robot column.  Target: under
10 s whole process on the 2-core machine.  Baseline, measured in the same run: the same ``diagnose`` without
``--confirm`` (what confirming adds is the difference).  Each command runs in a fresh process (``python -m
app.cli``), so the figure includes interpreter start-up and imports; wall and CPU time (user + system of the child)
are printed: on the shared, loaded machine the CPU time is the fairer figure.  Two held-out settings: the default
(5-fold whatever the number of poses, :data:`calib.diagnose.gap.DIAGNOSE_FOLDS`) and leave-one-out (``--folds 37``,
37 fits per candidate refit: the default up to 40 poses before 2026-11-26).

Run: ``python benchmarks/bench_confirm.py [--folds-only default|loo]``.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

TARGET_S = 10.0
ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data" / "figaroh-tiago-extra"
if not SHARED.exists():
    SHARED = Path("/work/shared/data/figaroh-tiago-extra")
TRAINING = SHARED / "qualisys_2021-11-30_static_postures.csv"
OTHERS = [SHARED / f"qualisys_2021-11-{s}_static_postures.csv" for s in ("26", "30-1403", "30-1504")]
OPTIONS = ["--robot", str(ROOT / "examples" / "tiago" / "tiago_mocap_sessions.toml"), "--angle-unit", "rad",
           "--length-unit", "m", "--noise-mm", "0.2", "--json"]


def run(argv: list[str]) -> tuple[float, float, dict]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "app.cli", *argv], capture_output=True, text=True, env=env, cwd=ROOT)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode:
        raise SystemExit(f"failed: {' '.join(argv)}\n{r.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, json.loads(r.stdout)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--folds-only", choices=("default", "loo"))
    a = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    for folds in ("default", "loo"):
        if a.folds_only and folds != a.folds_only:
            continue
        extra = [] if folds == "default" else ["--folds", "37"]
        title = "default (5-fold)" if folds == "default" else "leave-one-out (--folds 37)"
        b_wall, b_cpu, _ = run(["diagnose", str(TRAINING), *OPTIONS, *extra])
        confirm = [x for o in OTHERS for x in ("--confirm", str(o))]
        wall, cpu, j = run(["diagnose", str(TRAINING), *OPTIONS, *extra, *confirm])
        rms = "; ".join(f"{Path(c['source']).name}: {c['geometric_rms_mm']:.2f} -> {c['final_rms_mm']:.2f} mm"
                        for c in j["confirmation"])
        print(f"{title}: diagnose + 3 confirmations {wall:.1f} s wall, {cpu:.1f} s CPU (target < {TARGET_S:.0f} s "
              f"whole process); plain diagnose {b_wall:.1f} s wall, {b_cpu:.1f} s CPU; findings "
              f"{[f['label'] for f in j['findings']]}; exported {j['exported_model']['findings']}; {rms}")


if __name__ == "__main__":
    main()
