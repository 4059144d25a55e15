"""Benchmark: the reduction worker's part of ``robocal demo``'s waits (issue 26's speed line) -- what the recorder
waits for after the compliance procedure's last step (the pose set's model, for ISO 9283's compensated run) and after
the session's last step (the results).

The real worker process (``python -m app.live_reduction`` of the tree measured) is driven through its protocol over a
recorded demo database, procedure by procedure in the order recorded, as the recorder drives it, and its CPU time
(user + system, from ``/proc``) and the answer's latency are measured in three phases:

* ``model``: from the compliance procedure's completion (the procedures completed after it follow at once, as they
  do while the worker is busy) to the pose set's model received -- the recorder needs it about 0.27 s after that
  completion on a quiet machine;
* ``after``: what the worker does after handing the model out (the pose set's errors and held-out accuracy, the link,
  coupling and resolution stages), while the recorder records the compensated run (about 0.18 s);
* ``results``: from the last procedure's completion and ``finish`` to the scored results document received.

Before each phase the worker is left until it is idle (its CPU time still for 0.15 s), as it is while the recorder
records.  ``--compare OLD_TREE`` runs a second tree the same way, interleaved (one of each per round), so the
machine's load hits both alike; the figures are the medians and the paired differences.  One BLAS thread.

    python benchmarks/bench_live_reduction.py [--db DEMO.db] [--runs 5] [--compare OLD_TREE]

Without ``--db`` a demo database is recorded first with this tree (``robocal demo --seed 0``).
"""
from __future__ import annotations

import argparse
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
PHASES = ("model", "after", "results")
TICK_S = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process (Linux ``/proc``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK_S


def idle(pid: int, still_s: float = 0.15, limit_s: float = 20.0) -> None:
    """Wait until the process's CPU time has not moved for ``still_s``."""
    end, last, since = time.monotonic() + limit_s, cpu_s(pid), time.monotonic()
    while time.monotonic() < end:
        time.sleep(0.02)
        now = cpu_s(pid)
        if now != last:
            last, since = now, time.monotonic()
        elif time.monotonic() - since >= still_s:
            return


def one_run(tree: str, db: str, order: list[str]) -> dict[str, tuple[float, float]]:
    """The three phases' (worker CPU s, latency s) for one worker of ``tree`` on ``db``."""
    env = dict(os.environ, PYTHONPATH=tree, OPENBLAS_NUM_THREADS="1")
    proc = subprocess.Popen([sys.executable, "-m", "app.live_reduction"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, env=env, cwd=tree)

    def send(*msg):
        pickle.dump(msg, proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
        proc.stdin.flush()

    def receive(kind):
        while True:
            got = pickle.load(proc.stdout)
            if got[0] == "error":
                raise RuntimeError(f"{tree}: {got[2]}")
            if got[0] == kind:
                return got

    try:
        planned = list(dict.fromkeys(order))
        last = [p for i, p in enumerate(order) if p not in order[i + 1:]]      # in the order they complete
        send("open", db, planned, [], ["robocal", "demo"], ("identified",))
        k = last.index("compliance")
        for p in last[:k]:
            send("complete", [p])
        idle(proc.pid)
        out = {}
        c0, t0 = cpu_s(proc.pid), time.perf_counter()
        for p in last[k:-1]:                        # compliance and what completes while the worker is busy
            send("complete", [p])
        send("awaiting", "identified")
        receive("output")
        out["model"] = (cpu_s(proc.pid) - c0, time.perf_counter() - t0)
        c1 = cpu_s(proc.pid)
        idle(proc.pid)
        out["after"] = (cpu_s(proc.pid) - c1, float("nan"))
        c2, t2 = cpu_s(proc.pid), time.perf_counter()
        send("complete", [last[-1]])
        send("finish")
        receive("results")
        out["results"] = (cpu_s(proc.pid) - c2, time.perf_counter() - t2)
        return out
    finally:
        proc.kill()
        proc.wait()


def record_demo(folder: str) -> str:
    db = str(Path(folder) / "demo.db")
    env = dict(os.environ, PYTHONPATH=str(ROOT), ROBOCAL_LIVE_REDUCTION="0")
    subprocess.run([sys.executable, "-m", "app.cli", "demo", "--db", db], env=env, cwd=folder, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return db


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--db", help="a recorded demo database (default: record one with this tree)")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--compare", metavar="OLD_TREE", help="a second tree, run interleaved")
    args = ap.parse_args()
    trees = {"this": str(ROOT)} | ({"old": str(Path(args.compare).resolve())} if args.compare else {})
    with tempfile.TemporaryDirectory() as tmp:
        db = args.db or record_demo(tmp)
        from offline.reduction.session import load_session
        order = [s["procedure"] for s in load_session(db).steps]
        print(f"load average before: {os.getloadavg()}")
        got: dict[str, list[dict]] = {name: [] for name in trees}
        for r in range(args.runs + 1):              # the first round warms the bytecode and the disk cache
            for name, tree in trees.items():
                run = one_run(tree, db, order)
                if r:
                    got[name].append(run)
        print(f"load average after: {os.getloadavg()}")
    for ph in PHASES:
        line = [f"{ph:8s}"]
        for name in trees:
            cpu = statistics.median(x[ph][0] for x in got[name]) * 1e3
            lat = statistics.median(x[ph][1] for x in got[name]) * 1e3
            line.append(f"{name}: CPU {cpu:5.0f} ms" + ("" if lat != lat else f", answered in {lat:5.0f} ms"))
        if "old" in trees:
            diff = sorted((o[ph][0] - t[ph][0]) * 1e3 for t, o in zip(got["this"], got["old"]))
            line.append(f"paired CPU saving median {statistics.median(diff):.0f} ms ({diff[0]:.0f} .. {diff[-1]:.0f})")
        print(" | ".join(line))
    return 0


if __name__ == "__main__":
    sys.exit(main())
