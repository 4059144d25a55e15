"""``robocal plan``: design of experiments — which poses to measure, and how good a pose set is."""
from __future__ import annotations

import json

import numpy as np

from calib.errors import RobocalError
from calib.model import MeasurementModel
from calib.plan import INDICES, Design, observability, parameter_set, select_poses
from calib.posecsv import read_pose_csv, write_pose_csv
from calib.loading import load_robot
from calib.units import DEG

from acq.progress import progress_display
from acq.argtypes import add_robot_argument, examples_text, finite_float, output_file, positive_float, positive_int, seed_int

NAME = "plan"
HELP = "design the experiment: choose identification poses or score a pose set"
EXAMPLES = """\
robocal plan poses --count 40 --tool 50 0 100 --out poses.csv
robocal plan setup all --out setup.json
robocal plan check setup.json
"""

POSES_EXAMPLES = """\
robocal plan poses --count 40 --tool 50 0 100 --out poses.csv   # D-optimal (O1) poses, compared with random ones
robocal plan poses --count 40 --index O4                        # the noise-amplification index instead
robocal plan poses --evaluate poses.csv --set chapter6          # rank, condition, weakest combinations
"""
SETUP_EXAMPLES = """\
robocal plan setup all --out setup.json        # ruler, sweep targets and extended tool for this room
robocal plan setup sweep --room-x -1000 3000 --room-y 3500 --json
"""
CHECK_EXAMPLES = """\
robocal plan check setup.json                  # the standard plan against the set-up (exit 2 if a step fails)
robocal plan check cell.db --json              # a session's own plan
"""


def add_arguments(p):
    sub = p.add_subparsers(dest="what", metavar="WHAT", required=True)
    poses = sub.add_parser("poses", help="choose N poses maximising an observability index, or --evaluate a set",
                           epilog=examples_text(POSES_EXAMPLES))
    poses.add_argument("--count", type=positive_int, metavar="N", help="number of poses to choose")
    poses.add_argument("--evaluate", metavar="FILE.csv", help="score this pose set instead (columns q1..q6, deg)")
    add_robot_argument(poses)
    poses.add_argument("--out", type=output_file, metavar="FILE.csv", help="write the chosen poses (q1..q6 in degrees)")
    poses.add_argument("--index", choices=INDICES, default="O1", help="observability index (default O1, D-optimal)")
    poses.add_argument("--set", dest="pset", choices=("geometric", "full", "chapter6"), default="geometric",
                       help="parameters to identify (default: geometric)")
    poses.add_argument("--tool", nargs=3, type=finite_float, metavar=("X", "Y", "Z"),
                       help="tool target in frame 6, mm (default: the robot's tool point)")
    poses.add_argument("--noise-mm", type=positive_float, default=0.05, help="1-sigma point noise per coordinate (mm)")
    poses.add_argument("--seed", type=seed_int, default=0, help="seed of the random candidate poses")
    poses.add_argument("--json", action="store_true", help="print the result as JSON")
    setup = sub.add_parser("setup", help="set-up geometry of a Chapter 4 procedure for minimum estimation error",
                           epilog=examples_text(SETUP_EXAMPLES))
    setup.add_argument("procedure", choices=("ruler", "sweep", "te", "all"),
                       help="ruler pre-calibration, joint sweep (circle point analysis), transmission-error run, or "
                            "all three")
    setup.add_argument("--room-x", nargs=2, type=finite_float, metavar=("MIN", "MAX"), default=(-1500.0, 3500.0),
                       help="room extent along the baseline from theodolite A (mm)")
    setup.add_argument("--room-y", type=positive_float, default=4000.0, help="room depth in front of the baseline (mm)")
    setup.add_argument("--min-focus-mm", type=positive_float, default=900.0, help="closest sighting distance (mm)")
    setup.add_argument("--sigma-arcsec", type=positive_float, default=3.0, help="1-sigma reading noise (arc seconds)")
    setup.add_argument("--seed", type=seed_int, default=0, help="seed of the design's search")
    setup.add_argument("--json", action="store_true", help="print the result as JSON")
    setup.add_argument("--out", type=output_file, metavar="SETUP.json",
                       help="write the session set-up file with the design in it (read by robocal session --setup "
                            "and robocal demo --setup)")
    setup.add_argument("--setup", dest="base_setup", metavar="SETUP.json",
                       help="the set-up file to start from (default: the standard template)")
    check = sub.add_parser("check", help="pre-flight of a session's plan or of a set-up file against the robot "
                                         "(exit 2 when a step fails)", epilog=examples_text(CHECK_EXAMPLES))
    check.add_argument("target", metavar="SESSION_OR_SETUP",
                       help="a session database (.db) or a set-up JSON (checked with the standard plan)")
    add_robot_argument(check, "the set-up's robot, else the thesis's Puma 560")
    check.add_argument("--poses", metavar="POSES.csv", help="with a set-up: add this Chapter 6 pose set")
    check.add_argument("--json", action="store_true", help="print every failing check as JSON")


def _model(args) -> MeasurementModel:
    from calib.targets import with_targets

    robot = load_robot(args.robot)
    if args.tool is not None:
        robot = robot.with_tool({"P": np.array(args.tool, float)})
    if robot.is_tree and len(robot.tool_points_mm) > 1:
        # a branched robot: every pose measures every point, each identified with the tree
        return MeasurementModel(*with_targets(robot, list(robot.tool_points_mm)))
    return MeasurementModel(robot)


def run(args) -> int:
    if args.what == "poses":
        return _poses(args)
    if args.what == "setup":
        return _setup(args)
    if args.what == "check":
        return _check(args)
    raise RobocalError(f"plan: unknown subcommand {args.what!r}")


def _poses(args) -> int:
    model = _model(args)
    names = parameter_set(model, args.pset)
    if args.evaluate:
        return _evaluate(args, model, names)
    if args.count is None:
        raise RobocalError("plan poses: give --count N (poses to choose) or --evaluate FILE.csv")
    if args.count < 1:
        raise RobocalError(f"plan poses: --count must be positive, got {args.count}")
    with progress_display("plan poses") as update:
        plan = select_poses(model, args.count, names, args.index, args.noise_mm, args.seed, progress=update)
    robot = model.robot
    readings = plan.q_rad if robot.readings_are_joints else robot.readings_from_joints(plan.q_rad)
    if args.out:
        write_pose_csv(args.out, readings, prismatic=robot.reading_prismatic,
                       names=None if robot.readings_are_joints else robot.reading_names)
    if args.json:
        print(json.dumps({"count": len(plan.q_rad), "index": plan.index, "parameters": plan.names,
                          "held": plan.identifiability.fixed, "indices": plan.indices,
                          "random_indices": plan.random_indices,
                          "predicted_position_sigma_mm": plan.predicted_sigma_mm,
                          "random_position_sigma_mm": plan.random_sigma_mm,
                          "poses_deg": (readings / robot.reading_edge_scale).round(4).tolist(),
                          "joint_names": list(robot.reading_names), "out": args.out}, indent=2))
        return 0
    print(f"robocal plan poses: {len(plan.q_rad)} poses chosen for {len(plan.names)} identifiable parameters "
          f"({args.pset} set), index {plan.index}, point noise {args.noise_mm} mm")
    if plan.identifiability.fixed:
        print("  held (not identifiable from any pose with this tool and these observations): "
              + ", ".join(plan.identifiability.fixed))
    print(f"  {'index':<8}{'chosen':>12}{'random':>12}")
    for k in INDICES:
        print(f"  {k:<8}{plan.indices[k]:>12.4g}{plan.random_indices[k]:>12.4g}")
    ps, rs = plan.predicted_sigma_mm, plan.random_sigma_mm
    print(f"  predicted tool-position sigma over the test region: RMS {ps['rms']:.4f} mm, max {ps['max']:.4f} mm")
    print(f"  random poses of the same count:                    RMS {rs['rms']:.4f} mm, max {rs['max']:.4f} mm")
    if args.out:
        print(f"  written: {args.out}")
    else:
        print("  " + ", ".join(robot.reading_names) + " (deg; mm for a prismatic joint)")
        for row in readings / robot.reading_edge_scale:
            print("  " + "  ".join(f"{v:8.2f}" for v in row))
    return 0


def _evaluate(args, model: MeasurementModel, names: list[str]) -> int:
    table = read_pose_csv(args.evaluate, model.robot.n, model.robot.prismatic)
    outside = ~model.robot.within_limits(table.q_rad)
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise RobocalError(f"{args.evaluate}: pose {i + 1} is outside the joint limits of {model.robot.name}")
    design = Design(model, names, args.noise_mm)
    ident = design.analyse(table.q_rad)
    kept = design.restrict(ident.kept)
    J = kept.jacobian(table.q_rad)
    idx = observability(J / np.linalg.norm(J, axis=0))
    out = {"poses": table.n, "parameters": len(names), "observations": 3 * table.n, "rank": ident.rank,
           "condition": ident.condition, "held": ident.fixed, "kept_condition": ident.kept_condition,
           "indices_scaled": idx,
           "not_identifiable": [c.words(model.robot) for c in ident.unidentifiable],
           "weakest": [{"ratio": c.ratio, "words": c.words(model.robot)} for c in ident.weakest]}
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"robocal plan poses --evaluate {args.evaluate}: {table.n} poses, {3 * table.n} observations, "
          f"{len(names)} parameters ({args.pset} set)")
    for line in ident.report(model.robot):
        print("  " + line)
    print("  weakest combinations kept:")
    for c in ident.weakest:
        print(f"    ratio {c.ratio:.2e}: {c.words(model.robot)}")
    print("  observability (column-scaled): " + ", ".join(f"{k} {v:.3g}" for k, v in idx.items()))
    return 0


def _setup(args) -> int:
    from calib.setup_plan import FIXED_BY_SETUP, PROCEDURES, Constraints

    lo, hi = args.room_x
    if not lo < hi or args.room_y <= args.min_focus_mm or args.min_focus_mm <= 0 or args.sigma_arcsec <= 0:
        raise RobocalError("plan setup: the room must be larger than the minimum focus distance, and the noise "
                           "positive")
    c = Constraints(room_x_mm=(lo, hi), room_y_mm=args.room_y, min_focus_mm=args.min_focus_mm,
                    sigma_arcsec=args.sigma_arcsec)
    base = _base_setup(args)
    names = list(PROCEDURES) if args.procedure == "all" else [args.procedure]
    plans = []
    for name in names:
        # written into a set-up, a design takes the robot where the set-up stands it (its errors describe that file)
        fixed = {FIXED_BY_SETUP[name]: base["base_xyz_mm"]} if args.out and name in FIXED_BY_SETUP and \
            base.get("base_xyz_mm") else {}
        with progress_display(f"plan setup {name}") as update:
            plans.append(PROCEDURES[name](c, seed=args.seed, progress=update, **fixed))
    if args.out:
        _write_setup(args, plans, base)
    if args.json:
        docs = [{"procedure": p.procedure, "variables": p.variables, "errors": p.errors, "objective": p.objective,
                 "trend": p.trend, **({"note": p.note} if p.note else {})} for p in plans]
        print(json.dumps(docs[0] if len(docs) == 1 else docs, indent=2, default=float))
        return 0
    for plan in plans:
        _print_setup(plan)
    if args.out:
        print(f"  set-up written: {args.out} (check it with: robocal plan check {args.out})")
    return 0


def _base_setup(args) -> dict:
    """The set-up the design is written into: --setup (checked: a bad file is one line) or the standard template.
    --setup without --out would be read for nothing: an error, not a silently ignored option."""
    from acq.session.setup import standard_setup
    from acq.session.setup_file import read_partial_setup

    if not args.base_setup:
        return standard_setup()
    base = read_partial_setup(args.base_setup, ("stations", "ruler"))
    if not args.out:
        raise RobocalError(f"plan setup: --setup {args.base_setup} is the set-up the design is written into; it "
                           f"needs --out SETUP.json (nothing is written without it)")
    return base


def _write_setup(args, plans, base: dict) -> None:
    from calib.fileio import atomic_write_text
    from calib.setup_plan import into_setup

    base["stations"]["sigma_arcsec"] = args.sigma_arcsec
    base["min_focus_mm"] = args.min_focus_mm
    atomic_write_text(args.out, json.dumps(into_setup(plans, base), indent=2, default=float))


def _print_setup(plan) -> None:
    print(f"robocal plan setup {plan.procedure}: minimising the {plan.objective}")
    print("  set-up:  " + "  ".join(f"{k} {v:.1f}" for k, v in plan.variables.items()))
    print("  errors (1 sigma):  " + "  ".join(f"{k} {v:.4g}" for k, v in plan.errors.items()))
    if plan.note:
        print(f"  given:   {plan.note}")
    if plan.trend:
        keys = list(plan.trend[0])
        print("  trend with the other variables at their best values:")
        print("  " + "".join(f"{k:>18}" for k in keys))
        for row in plan.trend:
            print("  " + "".join(f"{row[k]:>18.4g}" for k in keys))


def _check(args) -> int:
    """``robocal plan check``: the pre-flight alone (:mod:`acq.session.preflight`), one line per failing step."""
    from acq.session.preflight import Preflight, failing_lines
    from acq.session.procedures import all_steps

    plan, setup, robot = _plan_and_setup(args)
    steps = all_steps(plan, setup)
    findings = Preflight(robot, setup).check(steps)
    lines = failing_lines(findings)
    if args.json:
        print(json.dumps({"steps": len(steps), "failing_steps": len(lines),
                          "failures": [{"key": f.key, "check": f.check, "value": f.value, "limit": f.limit,
                                        "unit": f.unit, "detail": f.detail} for f in findings]}, indent=2))
    else:
        for line in lines:
            print(line)
        print(f"robocal plan check {args.target}: {len(steps)} steps, "
              + (f"{len(lines)} fail the pre-flight" if lines else "all pass the pre-flight"))
    return 2 if lines else 0


def _plan_and_setup(args):
    """(plan, set-up with old keys mapped, robot) of a session database or a set-up JSON."""
    from pathlib import Path

    from acq.session.setup import session_setup, setup_robot
    from acq.session.setup_types import BenchSetup

    path = Path(args.target)
    if not path.is_file():
        raise RobocalError(f"{args.target}: no such file")
    if path.read_bytes()[:16] == b"SQLite format 3\x00":
        from app.commands.session import _stored_plan_setup
        plan, setup = _stored_plan_setup(str(path))
    else:
        from app.commands.session import default_plan
        from acq.session.setup_file import read_partial_setup
        setup = read_partial_setup(path, ("stations", "base_xyz_mm", "ruler"))
    robot = load_robot(args.robot) if args.robot else setup_robot(BenchSetup.of(setup))
    setup = BenchSetup.of(session_setup(setup, robot))          # checked as it was read (a partial file may lack a key)
    if not path.read_bytes()[:16] == b"SQLite format 3\x00":
        q = read_pose_csv(args.poses).q_rad / DEG if args.poses else None
        plan = setup.plan or default_plan(q, setup=setup, robot=robot)
    return plan, setup, robot
