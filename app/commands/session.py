"""``robocal session``: the Textual TUI that guides the operator through a calibration session.

Devices: ``--emulate`` wires the emulated instruments driven by the twin (the demo's wiring); otherwise each device
is named by URL, and the same drivers open it whatever it is (a serial port, ``socket://``, a pty, ``robocal://``):

    robocal session --db cell.db --setup setup.json \\
        --theodolite A=geocom:/dev/ttyUSB0 --theodolite B=geocom:/dev/ttyUSB1 --tap can:socketcan:can0

``--setup`` is the bench geometry (stations, ruler, tool targets, loads); ``robocal session --write-setup FILE``
writes an annotated template to start from.  ``--poses`` adds the Chapter 6 pose set (a CSV from
``robocal plan poses``).  An existing ``--db`` is resumed with the plan and set-up it was created with.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from calib.errors import RobocalError
from calib.fileio import atomic_write_text
from acq.argtypes import add_robot_argument, output_file, seed_int, te_joints
from app.interrupt import EXIT_HUNG_UP, EXIT_INTERRUPTED, command_line, report_text, say
from app.live_reduction import ReductionWorker, SessionReduction

NAME = "session"
HELP = "guide the operator through a calibration session (Textual TUI)"
EXAMPLES = """\
robocal session --emulate --db cell.db           # the emulated cell (resumes when cell.db exists)
robocal session --emulate --only ruler --only sweep/j2
robocal session --db cell.db --setup setup.json --tap can:socketcan:can0 \\
    --theodolite A=geocom:/dev/ttyUSB0 --theodolite B=geocom:/dev/ttyUSB1
"""


def add_arguments(p):
    p.add_argument("--db", type=output_file, metavar="PATH", default="session.db",
                   help="session database (created, or resumed if it exists; default session.db)")
    p.add_argument("--emulate", action="store_true",
                   help="use the emulated instruments driven by a simulated robot (the twin; the thesis's Puma 560, "
                        "or --robot's)")
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the emulated instruments")
    p.add_argument("--only", metavar="PREFIX", action="append", default=[],
                   help="run only the steps whose key starts with PREFIX (e.g. ruler, sweep/j2); repeatable")
    p.add_argument("--theodolite", metavar="NAME=KIND:URL", action="append", default=[],
                   help="a theodolite: station name (A, B), driver (geocom, gsi) and port URL; repeatable")
    p.add_argument("--tap", metavar="can:INTERFACE:CHANNEL | serial:URL",
                   help="the encoder tap (python-can interface and channel, or a serial URL)")
    p.add_argument("--setup", metavar="SETUP.json", help="bench geometry (see --write-setup)")
    p.add_argument("--poses", metavar="POSES.csv", help="Chapter 6 pose set (q1..q6, deg)")
    add_robot_argument(p, "the thesis's Puma 560; with --emulate, the robot the twin emulates; a resumed session "
                          "keeps the one it was recorded with")
    p.add_argument("--te-joints", type=te_joints, metavar="J,J,...", default=None,
                   help="joints whose transmission error a new session measures (default 4,6; 2 and 3 on request), "
                        "plan key transmission.joints")
    p.add_argument("--model", metavar="MODEL.json",
                   help="a calibrated model (robocal identify's model JSON) that commands ISO 9283's compensated run "
                        "of a new session; default: the model the session's own pose set (--poses) identifies")
    p.add_argument("--write-setup", type=output_file, metavar="FILE", help="write a set-up template (JSON) and exit")


def _only(prefixes):
    prefixes = tuple(prefixes)
    return (lambda step: step.key.startswith(prefixes)) if prefixes else None


def emulated_builder(db: str, seed: int, only: list[str] | tuple = (), te_joints=None, robot=None):
    """A TUI builder on the emulated rig (the demo's wiring: real drivers, emulated devices) in real time: a human
    watches the encoder windows and readings arrive at the pace a real cell gives them."""
    from acq.clock import RealClock
    from app.demo import build_demo
    from app.tui.app import SessionHandle

    keep = _only(only)

    def build(operator):
        resume = Path(db).exists() and Path(db).stat().st_size > 0
        worker = ReductionWorker.start()            # its imports overlap the session's building
        try:
            rig = build_demo(db, seed=seed, resume=resume, operator=operator, steps_filter=keep,
                             te_joints=te_joints, clock=RealClock(), robot=None if resume else robot)
        except BaseException:
            if worker is not None:
                worker.close()
            raise
        reduction = _reduced_beside(rig.runner, db, worker)

        def close():
            rig.close()
            reduction.close()

        return SessionHandle(rig.runner, close, f"emulated {rig.twin.robot.name} — {db}", db,
                             identities=rig.runner.rig.identities(), reduction=reduction)

    return build


def _reduced_beside(runner, db: str, worker):
    """The session's reduction beside the runner (:class:`app.live_reduction.SessionReduction`): its results when
    the session ends, and the pose set's model for ISO 9283's compensated commands; a failing worker is said in the
    session's log."""
    reduction = SessionReduction(runner, db, worker, tell=lambda text: runner.emit("log", text=text))
    if runner.command is not None and getattr(runner.command, "identified", False) is None:
        runner.command.identified = reduction.model
    return reduction


def parse_theodolite(text: str) -> tuple[str, str, str]:
    """``A=geocom:/dev/ttyUSB0`` -> (station, kind, url)."""
    name, eq, rest = text.partition("=")
    kind, colon, url = rest.partition(":")
    if not eq or not colon or not name or not kind or not url:
        raise RobocalError(f"session: --theodolite {text!r}: expected NAME=KIND:URL, e.g. A=geocom:/dev/ttyUSB0")
    return name.strip(), kind.strip(), url.strip()


def parse_tap(text: str) -> tuple[str, dict]:
    kind, _, rest = text.partition(":")
    if kind == "can":
        iface, colon, channel = rest.partition(":")
        if not colon or not iface or not channel:
            raise RobocalError(f"session: --tap {text!r}: expected can:INTERFACE:CHANNEL, e.g. can:socketcan:can0")
        return "can", {"interface": iface, "channel": channel}
    if kind == "serial" and rest:
        return "serial", {"url": rest}
    raise RobocalError(f"session: --tap {text!r}: expected can:INTERFACE:CHANNEL or serial:URL")


def default_plan(poses_deg=None, te_joints=None, setup=None, robot=None, model_path: str | None = None) -> dict:
    """The standard plan for a real cell (:func:`acq.session.plans.session_plan` with the :data:`CELL
    <acq.session.plans.CELL>` preset), with the operator's pose set when given; ``te_joints``: the
    transmission-error joints (``--te-joints``, plan key ``transmission.joints``; default the robot profile's).
    ``robot`` and ``setup`` default to the thesis's Puma on its standard bench; a set-up document has its old keys
    mapped here, a typed one (:class:`acq.session.setup_types.BenchSetup`) was mapped where it was read."""
    from acq.session.plans import CELL, session_plan
    from acq.session.setup import session_setup, standard_setup
    from acq.session.setup_types import BenchSetup
    from calib.loading import load_robot
    robot = load_robot(None) if robot is None else robot
    if not isinstance(setup, BenchSetup):
        setup = session_setup(standard_setup() if setup is None else setup, robot)
    return session_plan(robot, setup, CELL, te_joints, poses_deg, model_path=model_path)


def setup_template() -> dict:
    from acq.session.setup import standard_setup

    setup = standard_setup()
    setup["_comment"] = ("Bench geometry for robocal session. Lengths in mm, angles in degrees. stations: baseline L "
                         "and the circle offsets gamma1, gamma2 as first measured (the ruler procedure refines them);"
                         " base_xyz_mm: robot frame 0 in the theodolite frame, roughly; tool_target_mm: the target "
                         "on the flange (frame 6); extended_tool: targets A1, A2 for transmission errors; ruler: "
                         "mark positions along the ruler and where it is placed; compliance/link: levers, loads "
                         "(old keys) or "
                         "link, point_mm in frame j, masses_kg; sweep_radius_mm: radius of the sweep targets P_j; "
                         "far_target_mm: the instrument check's far target; robocal plan setup --out designs it.")
    return setup


def real_builder(db: str, theodolites: list[str], tap: str | None, setup_path: str | None, poses: str | None,
                 robot_path: str | None, only: list[str] | tuple = (), te_joints=None, model_path: str | None = None):
    """A TUI builder on real devices (or any device URL): opens them, creates or resumes the session."""
    from acq.drivers import open_theodolite
    from acq.encoders import open_tap
    from acq.session.preflight import Preflight
    from acq.session.setup import (predictor, record_robot, session_setup, setup_robot, setup_stations,
                                   station_names)
    from acq.session.stations import stations_from_store
    from offline.iso_commands import CompensatedCommands
    from acq.session.procedures import all_steps
    from acq.session.setup_types import setup_of
    from acq.session.rig import ManualBench, Rig
    from acq.session.runner import Runner
    from acq.session.store import SessionStore
    from app.tui.app import SessionHandle
    from calib.posecsv import read_pose_csv
    from calib.units import DEG

    specs = [parse_theodolite(t) for t in theodolites]
    tap_spec = parse_tap(tap) if tap else None
    resume = Path(db).exists() and Path(db).stat().st_size > 0
    if resume:
        plan, setup = _stored_plan_setup(db)
    else:
        if not setup_path:
            raise RobocalError("session: a new session needs --setup SETUP.json (robocal plan setup all --out FILE "
                               "designs one, robocal session --write-setup FILE writes a template)")
        from acq.session.setup_file import read_setup
        setup = read_setup(setup_path)
    if not resume:
        setup = record_robot(setup, robot_path)
    elif setup_path:
        _same_setup(db, setup, setup_path, robot_path)
    recorded = setup_of(setup)
    if resume and record_robot(setup, robot_path) != setup:
        raise RobocalError(f"session: {db} was recorded with the robot {recorded.robot or 'puma560 (default)'} "
                           f"(chain cut {recorded.base_link or '-'} -> {recorded.tip_link or '-'}): resume "
                           "it with the same --robot, or without --robot")
    robot = setup_robot(recorded)
    if not resume:
        q = read_pose_csv(poses, robot.n).q_rad / DEG if poses else None
    setup = session_setup(setup, robot)
    if not resume:
        if model_path:
            from calib.compensate import load_model
            given = load_model(model_path).nominal_robot   # a bad model file is one line before anything opens
            if given.n != robot.n or tuple(given.reading_names) != tuple(robot.reading_names):
                raise RobocalError(f"session: --model {model_path}: a model of {given.name} ({given.n} joints), "
                                   f"not of this session's robot {robot.name} ({robot.n} joints)")
        plan = default_plan(q, te_joints, setup, robot, model_path)
    bench = setup_of(setup)
    want = sorted(station_names(bench))
    if sorted(s[0] for s in specs) != want:
        raise RobocalError(f"session: give two theodolites, stations {' and '.join(want)} as the set-up names them "
                           f"(--theodolite {want[0]}=... --theodolite {want[1]}=...)")
    keep = _only(only)

    def build(operator):
        drivers = {}
        tap_dev = None
        worker = ReductionWorker.start()            # its imports overlap the devices' opening
        try:
            for st, kind, url in specs:
                drivers[st] = open_theodolite(kind, url, name=f"theodolite {st}")
            if tap_spec is not None:
                tap_dev = open_tap(tap_spec[0], robot=robot, **tap_spec[1])
        except Exception:
            for d in drivers.values():
                d.close()
            if worker is not None:
                worker.close()
            raise
        rig = Rig(drivers, tap_dev)
        rig.start()
        plan_d, setup_d = plan, setup
        if resume:
            store = SessionStore.open(db)
        else:
            store = SessionStore.create(db, "robocal session", plan_d, setup_d, operator="operator",
                                        metadata={"emulated": False})
        identities = rig.identities()
        for role, driver, url, ident in identities:
            rig.device_ids[role] = store.add_device(role, driver, url, ident, {})
        steps = all_steps(plan_d, bench)
        if keep is not None:
            steps = [s for s in steps if keep(s)]
        # the same wiring as the demo's: stations refitted from the session's own ruler steps, the pre-flight
        runner = Runner(store, rig, steps, operator, bench=ManualBench(), stations=setup_stations(bench),
                        predict=predictor(robot, bench),
                        refit_stations=lambda st: stations_from_store(st, bench),
                        preflight=Preflight(robot, bench),
                        command=CompensatedCommands(store, (plan_d.get("iso9283") or {}).get("model") or None))

        reduction = _reduced_beside(runner, db, worker)

        def close():
            rig.close()
            store.close()
            reduction.close()

        return SessionHandle(runner, close, f"{db}", db, identities=identities, reduction=reduction)

    return build


def _same_setup(db: str, stored: dict, setup_path: str, robot_path) -> None:
    """Resuming with --setup: the file is checked like any set-up file, and must be the one the session was recorded
    with -- a resumed session keeps its set-up (what was measured was measured with it), so another one is an error,
    not an option silently ignored."""
    from acq.session.setup import record_robot, session_setup, setup_robot
    from acq.session.setup_file import read_setup

    given = record_robot(read_setup(setup_path), robot_path)
    try:
        same = (json.dumps(session_setup(given, setup_robot(given)), sort_keys=True, default=float) ==
                json.dumps(stored, sort_keys=True, default=float))
    except RobocalError:
        same = False
    if not same:
        raise RobocalError(f"session: --setup {setup_path} cannot change a resumed session's set-up ({db} keeps the "
                           f"one it was recorded with): resume without --setup")


def _stored_plan_setup(db: str) -> tuple[dict, dict]:
    """The plan and set-up a session database was created with (read-only: nothing is touched)."""
    from offline.exchange import stored_plan_setup
    return stored_plan_setup(db)


def _need_terminal() -> None:
    """The TUI reads keys from stdin and draws on stderr: without a terminal there it would run unseen, a core busy,
    until killed -- so it refuses, in one line."""
    if not (sys.stdin.isatty() and sys.stderr.isatty()):
        raise RobocalError("session: needs a terminal (the TUI reads the keyboard on stdin and draws on stderr, and "
                           "one of them is not a terminal here); run it in a terminal, or record unattended with "
                           "robocal demo")


def run(args) -> int:
    if args.write_setup:
        atomic_write_text(args.write_setup, json.dumps(setup_template(), indent=2))
        print(f"robocal session: set-up template written to {args.write_setup}")
        return 0
    if args.te_joints and Path(args.db).exists() and Path(args.db).stat().st_size > 0:
        raise RobocalError(f"session: --te-joints cannot change a resumed session's plan ({args.db} keeps the one it "
                           f"was recorded with): resume without --te-joints, or start a new --db with it")
    if args.model and (args.emulate or Path(args.db).exists() and Path(args.db).stat().st_size > 0):
        raise RobocalError("session: --model applies to a new session on devices (an emulated session, or one "
                           "resumed, commands ISO 9283's compensated run with the model its plan already names or its "
                           "own pose set identifies)")
    if args.emulate:
        if args.robot and Path(args.db).exists() and Path(args.db).stat().st_size > 0:
            raise RobocalError(f"session: --robot cannot change a resumed session's robot ({args.db} keeps the one it "
                               f"was recorded with): resume without --robot")
        if args.setup:
            from acq.session.setup_file import read_setup
            read_setup(args.setup)                       # a bad file is reported as such wherever it is given
            raise RobocalError("session: --setup does not apply to --emulate (the emulated cell has its own "
                               "set-up; robocal demo --setup records an emulated session with a set-up file)")
        builder = emulated_builder(args.db, args.seed, args.only, args.te_joints, args.robot)
    elif args.theodolite:
        builder = real_builder(args.db, args.theodolite, args.tap, args.setup, args.poses, args.robot, args.only,
                               args.te_joints, args.model)
    else:
        raise RobocalError("session: give --emulate, or the devices (--theodolite A=KIND:URL --theodolite "
                           "B=KIND:URL [--tap ...]) and --setup")
    _need_terminal()
    from app.tui.app import RobocalApp

    app = RobocalApp(builder, resume_command=resume_command(args))
    app.run()
    return _after(app, args.db)


def _after(app, db: str) -> int:
    """What the terminal shows once the TUI is gone: the database, and either the command that makes the report
    (finished) or how many steps are kept and the command that resumes (stopped, quit, Ctrl-C, terminal closed)."""
    fin = app.finished or {}
    if fin.get("exit_status") == "success":
        say(f"robocal session: finished; data in {db}\n{report_text(db)}")
        return 0
    if fin.get("exit_status") == "refused" or app.handle is None and not app.progress.steps_total:
        say(f"robocal session: {fin.get('error') or 'not started'}; nothing recorded in {db}")
        return 1 if fin else 0
    why = {"interrupt": "interrupted", "hangup": "the terminal closed"}.get(app.ended_by or "", "")
    why = why or (f"stopped: {fin['error']}" if fin.get("error") else f"{fin.get('exit_status') or 'quit'}")
    say(f"robocal session: {why}: {app.kept()}")
    if app.ended_by:
        return EXIT_HUNG_UP if app.ended_by == "hangup" else EXIT_INTERRUPTED
    return 1 if fin.get("error") else 0


def resume_command(args) -> str:
    """The exact command that resumes this session: its database and devices, the same step filter; not what a
    resumed session keeps from its recording (set-up, poses, robot, transmission joints, seed)."""
    words = ["robocal", "session", "--db", args.db]
    words += ["--emulate"] if args.emulate else []
    for t in args.theodolite:
        words += ["--theodolite", t]
    words += ["--tap", args.tap] if args.tap else []
    for prefix in args.only:
        words += ["--only", prefix]
    return command_line(words)
