"""Are the demo's stated errors honest?  Seeded runs of the whole emulated session (every Chapter 4 procedure and
the pose set, through the drivers, the database and reprocessing), each estimate against the twin's truth.

Per procedure: how many estimates had a truth, the median of |value - truth| / error (0.67 for honest Gaussian
errors; the issue's band is 0.55-0.85) and the share within 2 sigma (95 %; band 90-99 %).  Estimates held at their
design values carry no error and are left out.  ``tests/fakes`` data (independent of the model) are scored by
``bench_error_honesty.py``; this script scores the demo as an operator would run it.

    python benchmarks/bench_demo_honesty.py --seeds 12          # about 20 s a seed on an idle 2-core machine
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: how an estimate's name maps to the procedure it comes from (first matching prefix)
PROCEDURES = (("ruler.", "ruler (L, gammas, B's height)"), ("dh.", "sweeps: DH parameters"),
              ("misalign.", "sweeps: misalignments"), ("comp.", "sweeps: compensation scheme (eqs 4.3.12-15)"),
              ("te.", "transmission error"),
              ("compliance.", "joint compliance"), ("link.", "link compliance"), ("coupling.", "coupling"),
              ("resolution.", "encoder resolution"), ("ident.j", "pose set: geometry"),
              ("ident.base", "pose set: geometry"), ("ident.tool", "pose set: geometry"),
              ("ident.", "pose set: running errors"))


def procedure_of(name: str) -> str:
    return next((label for prefix, label in PROCEDURES if name.startswith(prefix)), "other")


def ratios(estimates: list[dict]) -> list[tuple[str, str, float]]:
    """(procedure, name, (value - truth) / error) of every estimate with a truth and a finite, non-zero error."""
    out = []
    for e in estimates:
        t, err = e.get("truth"), e.get("error")
        if t is None or e.get("held") or not err or not np.isfinite(err):
            continue
        out.append((procedure_of(e["name"]), e["name"], (e["value"] - t) / err))
    return out


def run_seed(seed: int, workdir: Path) -> list[dict]:
    from acq.session.demo import build_demo
    from acq.session.reprocess import reprocess
    db = workdir / f"demo-{seed}.db"
    demo = build_demo(db, seed=seed)
    try:
        state = demo.runner.run()
    finally:
        demo.close()
    if state != "finished":
        raise SystemExit(f"bench_demo_honesty: seed {seed}: the session ended {state}")
    return reprocess(str(db))["estimates"]


def table(rows: list[tuple[str, str, float]]) -> list[dict]:
    by: dict[str, list[float]] = {}
    for proc, _, z in rows:
        by.setdefault(proc, []).append(z)
    order = list(dict.fromkeys(label for _, label in PROCEDURES))
    out = []
    for proc in sorted(by, key=lambda p: order.index(p) if p in order else len(order)):
        z = np.abs(np.array(by[proc]))
        out.append({"procedure": proc, "n": int(z.size), "median": float(np.median(z)),
                    "within_2sigma": float(np.mean(z < 2.0))})
    z = np.abs(np.array([r[2] for r in rows]))
    out.append({"procedure": "all", "n": int(z.size), "median": float(np.median(z)),
                "within_2sigma": float(np.mean(z < 2.0))})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=12, help="number of seeded demo runs (default 12)")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--json", help="write every ratio here")
    ap.add_argument("--worst", type=int, default=8, help="list the worst ratios (default 8)")
    args = ap.parse_args(argv)
    rows: list[tuple[str, str, float]] = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            r = ratios(run_seed(seed, Path(tmp)))
            rows += [(p, f"{n} (seed {seed})", z) for p, n, z in r]
            print(f"seed {seed}: {len(r)} estimates with a truth, {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    print(f"{'procedure':32s} {'values':>7s} {'median |v-t|/err':>17s} {'within 2 sigma':>15s}")
    for row in table(rows):
        flag = "" if 0.55 <= row["median"] <= 0.85 and 0.90 <= row["within_2sigma"] <= 0.99 else "  (outside the band)"
        print(f"{row['procedure']:32s} {row['n']:7d} {row['median']:17.2f} {100 * row['within_2sigma']:14.1f}%{flag}")
    print("honest: median 0.67, 95 % within 2 sigma; the issue's band: 0.55-0.85 and 90-99 %")
    for proc, name, z in sorted(rows, key=lambda r: -abs(r[2]))[:args.worst]:
        print(f"  worst: {name} {z:+.2f} sigma ({proc})")
    if args.json:
        Path(args.json).write_text(json.dumps([{"procedure": p, "name": n, "ratio": z} for p, n, z in rows]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
