"""``robocal demo``: record a complete emulated calibration session (every Chapter 4 procedure and the Chapter 6 pose
set) with a scripted operator, then reprocess it.  The instruments are the real drivers on emulators driven by the
twin; see :mod:`app.demo`.
"""
from __future__ import annotations

import gc
import json
import sys
import time
from pathlib import Path

from calib.errors import RobocalError
from calib.fileio import atomic_write_text
from acq.argtypes import add_robot_argument, output_dir, output_file, seed_int, te_joints
from app.interrupt import HungUp, command_line, exit_status, hangups_interrupt, kept_text, report_text, say
from app.live_reduction import ReductionWorker, SessionReduction

NAME = "demo"
HELP = "record an emulated calibration session of every procedure, then reprocess it"
EXAMPLES = """\
robocal demo                                    # record an emulated session (robocal-demo.db), reprocess it
robocal demo --db run.db --report report/ --pdf   # ... and write the report, HTML and PDF
robocal demo --db run.db --resume               # continue an interrupted one
"""


def add_arguments(p):
    p.add_argument("--db", type=output_file, default=None,
                   help="session database to write (default robocal-demo.db, or the next free robocal-demo-N.db)")
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the emulated instruments' noise")
    p.add_argument("--resume", action="store_true", help="continue an interrupted demo session in --db")
    p.add_argument("--json", type=output_file, metavar="OUT", help="write the estimates JSON here ('-' for stdout)")
    p.add_argument("--report", type=output_dir, metavar="DIR", help="write the HTML report here")
    p.add_argument("--overwrite", action="store_true", help="replace an existing --db")
    p.add_argument("--setup", metavar="SETUP.json",
                   help="set-up file (robocal plan setup --out): ruler, targets, loads; the emulated cell keeps its "
                        "own stations and robot base")
    p.add_argument("--te-joints", type=te_joints, metavar="J,J,...", default=None,
                   help="joints whose transmission error the session measures (default 4,6; 2 and 3 on request)")
    add_robot_argument(p, "the thesis's Puma 560; another robot's twin and bench come from its description, and "
                          "every procedure that applies to it is recorded")
    add_report_options(p)


def run(args) -> int:
    # no cyclic garbage collection in the demo: what the session builds lives as long as the process, and what the
    # recording allocates is freed by reference counting -- 84-360 objects were left in cycles after a whole demo
    # (a peak of 66.8-74.9 MB against 64.6 MB), where 87 collections spent 30-45 ms looking for them.  The demo's
    # plan bounds it (a session in the TUI, open for hours, keeps the collector)
    gc.disable()
    try:
        return _run(args)
    finally:
        gc.enable()


def _run(args) -> int:
    from app.demo import build_demo

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
    base = None
    if args.setup:
        from acq.session.setup_file import read_partial_setup
        base = read_partial_setup(args.setup, ("ruler",))        # a bad file is reported as such, resumed or not
        if args.resume:
            raise RobocalError(f"demo: --setup cannot change a resumed session's set-up ({db} keeps the one it was "
                               f"recorded with): resume without --setup, or start a new --db with it")
    if args.resume and args.te_joints:
        raise RobocalError(f"demo: --te-joints cannot change a resumed session's plan ({db} keeps the one it was "
                           f"recorded with): resume without --te-joints, or start a new --db with it")
    check_pdf_options(args)
    t0 = time.perf_counter()
    if args.te_joints and not args.resume:     # checked against the robot's planned runs before anything is built
        from acq.session.plans import transmission_plan
        from calib.profile import profile_of
        from calib.loading import load_robot
        transmission_plan(args.te_joints, profile=profile_of(load_robot(args.robot)))
    if args.resume and args.robot:
        raise RobocalError(f"demo: --robot cannot change a resumed session's robot ({db} keeps the one it was "
                           f"recorded with): resume without --robot")
    worker = ReductionWorker.start()            # its imports overlap the session's building
    try:
        demo = build_demo(db, seed=args.seed, resume=args.resume, setup=base, te_joints=args.te_joints,
                          robot=args.robot)
        res = _record(demo, db, _resume_command(args, db), worker, t0)
    finally:
        if worker is not None:
            worker.close()
    if isinstance(res, int):                    # the session did not finish: what was kept is said
        return res
    _summary(res, args.verbose, args.tolerance_mm)
    if args.report:
        from offline.report import write_report
        print(f"report: {write_report(res, args.report, tolerance_mm=args.tolerance_mm, pdf=args.pdf)}",
              file=sys.stderr)
    else:
        say(f"session database: {db}; {report_text(str(db))}")
    if args.json:
        _write_json(res, args.json)
    print(f"total {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


def _record(demo, db: Path, resume: str, worker: ReductionWorker | None, t0: float) -> dict | int:
    """Record the session, then reduce it: its results, or the exit status when it did not finish (what was kept
    and how to resume are said).  With a ``worker`` the session is reduced while it records, procedure by procedure
    (:mod:`app.live_reduction`); without one, or when it fails, after it, in this process."""
    from acq.progress import progress_display
    from acq.session.headless import ProgressPrinter
    say(f"recording the session into {db} (Ctrl-C stops it; every step saved is kept)")
    pp = ProgressPrinter()
    res = None
    every = demo.runner.steps
    live = SessionReduction(demo.runner, str(db), worker, progress=_reprocessing)
    try:
        with hangups_interrupt():
            with progress_display("recording session", after_s=0.5) as update:
                pp.update = lambda done, total, key: update(key, done / max(total, 1))
                demo.runner.subscribe(pp)
                # the steps commanded by the calibrated model wait for the model this session's reduction gives
                demo.runner.steps = [s for s in every if not s.setup.get("command")]
                state = demo.runner.run()
            if state == "finished" and len(demo.runner.steps) < len(every):
                res, state = _compensated_run(demo, every, live)
    except KeyboardInterrupt as exc:             # Ctrl-C or a closed terminal: say what was kept, and where
        saved, total = len(demo.store.done_keys()), len(every)
        say(f"{'the terminal closed' if isinstance(exc, HungUp) else 'interrupted'}: "
            f"{kept_text(saved, total, str(db), resume)}")
        return exit_status(exc)
    finally:
        demo.close()
    clock = demo.runner.rig.clock
    simulated = f", {clock.now():.1f} s of instrument time simulated" if clock.simulated else ""
    print(f"session {db}: {state}, {pp.saved}/{pp.total} steps saved in {time.perf_counter() - t0:.1f} s "
          f"({pp.failed_checks} failed checks, repeated or noted{simulated})", file=sys.stderr)
    if state == "refused":
        for line in pp.preflight_lines:
            print(f"pre-flight: {line}", file=sys.stderr)
        raise RobocalError(f"session {db}: the pre-flight failed for {len(pp.preflight_lines)} step(s) (listed "
                           f"above); nothing was recorded")
    if state != "finished":                      # paused, aborted, or failed on a device
        why = f" ({pp.error})" if pp.error else ""
        say(f"the session ended {state}{why}: {kept_text(pp.saved, pp.total, str(db), resume)}")
        return 1
    return res if res is not None else live.results(while_waiting=_load_summary)


def _load_summary() -> None:
    """What prints the summary, loaded while the reduction worker ends the results (its import compiles the words
    of every kind of estimate: 15-35 ms that were the recorder's after the last answer)."""
    # imported for its side effect: loaded now, used by _summary
    import offline.summary  # noqa: F401


def _reprocessing():
    from acq.progress import progress_display
    return progress_display("reprocessing", after_s=0.5)


def _compensated_run(demo, every: list, live: SessionReduction) -> tuple[dict | None, str]:
    """ISO 9283 with compensation on, as a calibrated controller runs it: the model the session's pose set identifies
    (:class:`app.live_reduction.SessionReduction`), the remaining steps commanded by that model
    (:class:`offline.iso_commands.CompensatedCommands`); the results are then the whole session's reduction -- the
    calibration itself is not repeated. Returns the results when already made (no model: no compensated run) and the
    runner's final state."""
    doc = live.model()
    if doc is None:                             # no model: the problems say why
        say("ISO 9283: the compensated run was not recorded: the session's pose set gave no calibrated model")
        return live.results(), "finished"
    from calib.compensate import MODEL_SCHEMA
    from calib.jsonfile import vouch
    demo.runner.command.use(vouch(doc, MODEL_SCHEMA))      # the model this session's reduction made
    demo.runner.steps = every
    return None, demo.runner.run()


def _resume_command(args, db: Path) -> str:
    """The exact command that continues this demo: its database with --resume and the outputs asked for (the seed,
    set-up and plan are the database's own)."""
    words = ["robocal", "demo", "--resume", "--db", str(db)]
    for flag, value in (("--json", args.json), ("--report", args.report), ("--tolerance-mm", args.tolerance_mm)):
        if value is not None:
            words += [flag, str(value)]
    words += [flag for flag, on in (("--pdf", args.pdf), ("--verbose", args.verbose)) if on]
    return command_line(words)


def _write_json(res: dict, out: str) -> None:
    doc = {k: v for k, v in res.items() if k != "figures"}
    text = json.dumps(doc, indent=1)
    if out == "-":
        print(text)
    else:
        atomic_write_text(out, text)


def _summary(res: dict, verbose: bool = False, tolerance_mm: float | None = None) -> None:
    """The compact summary per procedure and the accuracy before/after (every estimate with ``verbose``)."""
    from offline.summary import print_summary, tolerance_lines
    print_summary(res, verbose=verbose)
    for line in tolerance_lines(res.get("accuracy"), tolerance_mm):
        print(line)


def check_pdf_options(args) -> None:
    """``--pdf`` is the report printed: it needs ``--report`` and a renderer, both checked before any work."""
    if args.pdf:
        if not args.report:
            raise RobocalError("--pdf needs --report DIR (the PDF is the report printed, written beside report.html)")
        from offline.pdf import require_renderer
        require_renderer()


def add_report_options(p) -> None:
    """Options of what the operator sees, shared by ``demo`` and ``reprocess``."""
    from acq.argtypes import positive_float
    p.add_argument("--verbose", action="store_true", help="print every estimate, not only the summary")
    p.add_argument("--tolerance-mm", type=positive_float, default=None,
                   help="position tolerance the calibrated robot must meet (report verdict)")
    p.add_argument("--pdf", action="store_true",
                   help="with --report, also write report.pdf: the same report printed by headless Chromium (or "
                        "WeasyPrint); one line, exit 2, when neither is installed")
