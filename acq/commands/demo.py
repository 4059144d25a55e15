"""``robocal demo``: record a complete emulated calibration session (every Chapter 4 procedure and the Chapter 6 pose
set) with a scripted operator, then reprocess it.  The instruments are the real drivers on emulators driven by the
twin; see :mod:`acq.session.demo`.
"""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from calib.errors import RobocalError
from calib.fileio import atomic_write_text
from acq.argtypes import output_dir, output_file, seed_int

NAME = "demo"
HELP = "record an emulated calibration session of every procedure, then reprocess it"


def add_arguments(p):
    p.add_argument("--db", type=output_file, default=None,
                   help="session database to write (default robocal-demo.db, or the next free robocal-demo-N.db)")
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the emulated instruments' noise")
    p.add_argument("--resume", action="store_true", help="continue an interrupted demo session in --db")
    p.add_argument("--json", type=output_file, metavar="OUT", help="write the estimates JSON here ('-' for stdout)")
    p.add_argument("--report", type=output_dir, metavar="DIR", help="write the HTML report here")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --db")


def run(args) -> int:
    from acq.progress import progress_display
    from acq.session.demo import build_demo
    from acq.session.headless import ProgressPrinter
    from acq.session.reprocess import reprocess

    if args.db is None:
        # the main job must run again on the same machine: never touch an earlier demo, take the next free name
        db = Path("robocal-demo.db")
        n = 2
        while not args.resume and db.exists():
            db = Path(f"robocal-demo-{n}.db")
            n += 1
    else:
        db = Path(args.db)
    if args.overwrite and not args.resume:
        for suffix in ("", "-wal", "-shm"):
            Path(str(db) + suffix).unlink(missing_ok=True)
    if db.exists() and not args.resume:
        raise RobocalError(f"{db}: exists already; use --resume to continue it, --overwrite to replace it")
    t0 = time.perf_counter()
    demo = build_demo(db, seed=args.seed, resume=args.resume)
    try:
        with progress_display("recording session", after_s=0.5) as update:
            pp = ProgressPrinter(lambda done, total, key: update(key, done / max(total, 1)))
            demo.runner.subscribe(pp)
            state = demo.runner.run()
    finally:
        demo.close()
    t_rec = time.perf_counter() - t0
    print(f"session {db}: {state}, {pp.saved}/{pp.total} steps saved in {t_rec:.1f} s "
          f"({pp.failed_checks} failed checks, repeated or noted)", file=sys.stderr)
    if state != "finished":
        raise RobocalError(f"session {db} ended {state}; continue it with: robocal demo --resume --db {db}")
    with progress_display("reprocessing", after_s=0.5) as update:
        res = reprocess(str(db), progress=update)
    _summary(res)
    if args.report:
        from acq.session.report import write_report
        print(f"report: {write_report(res, args.report)}", file=sys.stderr)
    if args.json:
        _write_json(res, args.json)
    print(f"total {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


def _write_json(res: dict, out: str) -> None:
    doc = {k: v for k, v in res.items() if k != "figures"}
    text = json.dumps(doc, indent=1)
    if out == "-":
        print(text)
    else:
        atomic_write_text(out, text)


def _summary(res: dict) -> None:
    from rich.console import Console
    from rich.table import Table
    t = Table(title=f"estimates from {res['session']['title']}")
    for c in ("name", "value", "error (1 sigma)", "unit", "truth"):
        t.add_column(c)
    for e in res["estimates"]:
        err = "held" if e.get("held") else f"{e['error']:.2g}"
        t.add_row(e["name"], f"{e['value']:.6g}", err, e["unit"], "" if e["truth"] is None else f"{e['truth']:.6g}")
    Console().print(t)
    for p in res["problems"]:
        print(f"note: {p}", file=sys.stderr)
