"""``robocal session``: the Textual TUI that guides the operator through a calibration session."""
from __future__ import annotations

from pathlib import Path

from calib.errors import RobocalError

NAME = "session"
HELP = "guide the operator through a calibration session (Textual TUI)"


def add_arguments(p):
    p.add_argument("--db", metavar="PATH", default="session.db",
                   help="session database (created, or resumed if it exists; default session.db)")
    p.add_argument("--emulate", action="store_true",
                   help="use the emulated instruments driven by the simulated Puma 560 (the twin)")
    p.add_argument("--seed", type=int, default=0, help="seed of the emulated instruments")
    p.add_argument("--only", metavar="PREFIX", action="append", default=[],
                   help="run only the steps whose key starts with PREFIX (e.g. ruler, sweep/j2); repeatable")


def emulated_builder(db: str, seed: int, only: list[str] | tuple = ()):
    """A TUI builder on the emulated rig (the demo's wiring: real drivers, emulated devices)."""
    from acq.session.demo import build_demo
    from acq.tui.app import SessionHandle

    prefixes = tuple(only)
    keep = (lambda step: step.key.startswith(prefixes)) if prefixes else None

    def build(operator):
        resume = Path(db).exists() and Path(db).stat().st_size > 0
        rig = build_demo(db, seed=seed, resume=resume, operator=operator, steps_filter=keep)
        return SessionHandle(rig.runner, rig.close, f"emulated Puma 560 — {db}", db,
                             identities=rig.runner.rig.identities())

    return build


def run(args) -> int:
    if not args.emulate:
        raise RobocalError("session: connecting real instruments from the TUI is not available yet; use --emulate "
                           "(real devices: robocal emulate shows the URLs the drivers open)")
    from acq.tui.app import RobocalApp

    app = RobocalApp(emulated_builder(args.db, args.seed, args.only))
    app.run()
    if app.finished and app.finished.get("error"):
        print(f"robocal session: stopped: {app.finished['error']} — the session resumes with the same --db")
        return 1
    print(f"robocal session: data in {args.db}")
    return 0
