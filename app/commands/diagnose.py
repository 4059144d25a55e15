"""``robocal diagnose``: explain the sim-to-real gap of a robot from pose measurements (issue 8).

DATA is a pose-measurement CSV (any robot description's joint names, units by --angle-unit / --length-unit) or a
session database (once the session store exports observations).
"""
from __future__ import annotations

import json
import sys

from app.commands._csvargs import add_order_arguments, add_unit_arguments, order_options, units
from acq.argtypes import (add_force_argument, add_robot_argument, float_range, nonneg_int, output_dir, positive_float,
                          positive_int)
from calib.errors import RobocalError
from calib.outliers import LOSSES, OUTLIER_MODES

NAME = "diagnose"
HELP = "diagnose the sim-to-real gap: held-out residual, where it lies, which unmodelled effect, how far it shrinks"
EXAMPLES = """\
robocal diagnose poses.csv --report diag/       # where model and measurements disagree, and why
robocal diagnose examples/demo-session.db --json # a session database works too
robocal diagnose --validate --seeds 5           # withheld-effect study on the twin
"""


def add_outlier_arguments(p) -> None:
    """--outliers and --loss, shared by identify and diagnose (one implementation: calib.outliers)."""
    p.add_argument("--outliers", choices=OUTLIER_MODES, default="flag",
                   help="poses with implausible residuals: flag (report, keep; default), reject (leave out, unless "
                        "they cluster in a pose condition: then they are a systematic effect and kept), off")
    p.add_argument("--loss", choices=LOSSES, default="linear",
                   help="loss of the least-squares fit (scipy least_squares): linear (plain), huber, cauchy, soft_l1")


def add_arguments(p):
    p.add_argument("data", metavar="DATA", nargs="?",
                   help="pose CSV (q1..qn deg, x y z mm, optional dir*, payload, temperature, time, sigma_*_mm), "
                        "or a session database")
    add_robot_argument(p)
    add_unit_arguments(p)
    add_order_arguments(p)
    p.add_argument("--noise-mm", type=positive_float, default=None, metavar="S",
                   help="1-sigma point noise per coordinate (mm) when DATA carries no per-point uncertainty")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.add_argument("--report", type=output_dir, metavar="DIR", help="write an HTML report with PNG figures into DIR")
    p.add_argument("--geometry", choices=("auto", "full", "offsets"), default="auto",
                   help="geometric parameter set of the baseline (auto: full unless the poses are too few)")
    p.add_argument("--folds", type=positive_int, default=None, metavar="K",
                   help="k-fold held-out test (default 5, whatever the number of poses; K = the number of poses is "
                        "leave-one-out)")
    p.add_argument("--alpha", type=float_range(0, 1, low_open=True, high_open=True), default=0.01,
                   help="family-wise significance level of the nested F-test (default 0.01)")
    p.add_argument("--max-effects", type=nonneg_int, default=8, metavar="N",
                   help="stop after N accepted effects (default 8: room for a stand-in that a later effect supersedes and "
                        "the backward step drops)")
    add_outlier_arguments(p)
    add_force_argument(p)
    p.add_argument("--confirm", metavar="OTHER.csv", action="append",
                   help="independent data (another day or set-up; repeat for several sessions): refit only the base "
                        "per station group and say, per finding and session, whether it shrinks the gap there too, "
                        "with the finding refitted on that session alone")
    p.add_argument("--out", metavar="MODEL.json",
                   help="write the final model (geometry and findings; with --confirm only the findings confirmed on "
                        "at least one session) as robocal identify writes it, for evaluate and compensate")
    p.add_argument("--validate", action="store_true",
                   help="run the withheld-effect validation on twin data instead of diagnosing DATA")
    p.add_argument("--seeds", type=positive_int, default=3, metavar="N", help="seeds per case for --validate (default 3)")
    p.add_argument("--levels", default="2,4", metavar="L1,L2",
                   help="--validate: effect sizes as multiples of the noise floor (tool-point displacement RMS; "
                        "default 2,4)")
    p.add_argument("--clean", type=nonneg_int, default=4, metavar="N", help="--validate: clean cases per seed (default 4)")
    p.add_argument("--workers", type=positive_int, default=None, metavar="N", help="processes for --validate (default: CPUs)")
    p.add_argument("--suite", choices=("twin", "independent", "all"), default="all",
                   help="--validate: the withheld-effect study on twin data, the harder families from the independent "
                        "generator (two effects, near the floor, outside the library, heavy tails, few poses, wrong "
                        "--noise-mm), or both (default)")


def _validate(args) -> int:
    from sim.validate import cases, run_validation

    from acq.progress import progress_display

    if args.seeds < 1:
        raise RobocalError(f"--seeds must be at least 1, got {args.seeds}")
    try:
        levels = tuple(float(x) for x in args.levels.split(","))
    except ValueError:
        raise RobocalError(f"--levels must be numbers separated by commas, got {args.levels!r}") from None
    if not levels or min(levels) <= 0:
        raise RobocalError(f"--levels must be positive, got {args.levels!r}")
    if args.clean < 0:
        raise RobocalError(f"--clean must not be negative, got {args.clean}")
    v = fam = None
    with progress_display("robocal diagnose --validate") as update:
        if args.suite in ("twin", "all"):
            v = run_validation(cases(seeds=args.seeds, levels=levels, clean_per_seed=args.clean),
                               workers=args.workers, progress=update)
        if args.suite in ("independent", "all"):
            from sim.families import family_cases, run_families
            fam = run_families(family_cases(seeds=args.seeds), workers=args.workers, progress=update)
    if args.report and v is not None:
        from calib.diagnose.report import write_validation_report
        write_validation_report(v, args.report)
    if args.json:
        doc = v.to_json() if v is not None else {}
        if fam is not None:
            doc["independent"] = fam.to_json()
        print(json.dumps(doc, indent=1))
    else:
        print("\n\n".join(x.render() for x in (v, fam) if x is not None))
        if args.report and v is not None:
            print(f"\nreport: {args.report}/validation.html")
    return 0


def _read(path: str, robot, noise_mm, csv_units: dict | None = None):
    """DATA as DiagnosisData: a session database through the session layer (plain arrays), else the file loader."""
    from calib.diagnose.data import from_session_arrays, is_session_db, load_data

    if is_session_db(path):
        from offline.exchange import pose_arrays, session_robot
        return from_session_arrays(robot or session_robot(str(path)), pose_arrays(str(path)), str(path))
    return load_data(path, robot, noise_mm, **(csv_units or {}))


def _plausible(data, args) -> list[dict]:
    """The data (DATA, and OTHER of --confirm) checked against the description before the fits, as identify checks
    its data (calib.plausibility: joint columns the robot lacks, units, distinct poses); after the fits, the
    baseline's chi-square is checked by :func:`run`."""
    from calib.identify import default_free
    from calib.model import MeasurementModel
    from calib.plausibility import check_data, enforce
    nominal = MeasurementModel(data.robot)
    return enforce(check_data(nominal, data.q_rad, data.points_mm, data.source,
                              n_free=len(default_free(nominal, effects=False)), prismatic=data.robot.prismatic,
                              ignored_columns=data.ignored_columns, target=data.labels.get("target")),
                   args.force_implausible, "diagnose")


def run(args) -> int:
    if args.validate:
        return _validate(args)
    if not args.data:
        raise RobocalError("diagnose: give DATA (a pose CSV or a session database), or --validate")
    if args.noise_mm is not None and not args.noise_mm > 0:
        raise RobocalError(f"diagnose: --noise-mm must be positive, got {args.noise_mm}")
    if args.folds is not None and args.folds < 2:
        raise RobocalError(f"diagnose: --folds must be at least 2, got {args.folds}")
    if not 0 < args.alpha < 1:
        raise RobocalError(f"diagnose: --alpha must be between 0 and 1, got {args.alpha}")
    from calib.diagnose import diagnose
    from calib.diagnose.render import render
    from calib.loading import load_robot

    from acq.progress import progress_display

    robot = load_robot(args.robot) if args.robot else None
    data = _read(args.data, robot, args.noise_mm, {**units(args), **order_options(args)})
    # every file read and checked before the (long) diagnosis: a file for another robot is refused at once
    others = [_read(path, data.robot, args.noise_mm, {**units(args), **order_options(args)})
              for path in args.confirm or ()]
    implausible = _plausible(data, args)
    for other in others:
        implausible += _plausible(other, args)
    with progress_display("robocal diagnose") as update:
        diag = diagnose(data, level=args.geometry, n_folds=args.folds, alpha=args.alpha,
                        max_effects=args.max_effects, outliers=args.outliers, loss=args.loss, progress=update,
                        # the sessions of --confirm test the findings on data no choice has seen: the training
                        # set's own nested cross-validation (five times the cost) would add no held-out figure
                        nested="the sessions of --confirm are the held-out test" if others else True)
    from calib.plausibility import check_fit, enforce
    implausible += enforce(check_fit(diag.geometric.all_fit.reduced_chi2, str(args.data)), args.force_implausible,
                           "diagnose")
    from calib.diagnose.export import exported_model
    exported = exported_model(diag)
    if others:
        from calib.diagnose.confirm import confirm_all
        diag.confirmation = confirm_all(diag, others)
        exported = diag.confirmation.exported
    if diag.warning():
        print(f"warning: {diag.warning()}", file=sys.stderr)
    from calib.provenance import provenance
    prov = provenance(args.robot or data.robot.source)
    if args.out:
        from calib.compensate import save_model
        save_model(args.out, exported.model, exported.ident, provenance=prov)
    if args.report:
        from calib.diagnose.report import write_report
        write_report(diag, args.report, provenance=prov)
    if args.json:
        extra = {"plausibility_warnings": implausible} if implausible else {}
        extra["exported_model"] = {**exported.as_dict(), "path": args.out}
        from calib.names import with_joint_names
        print(json.dumps({**with_joint_names(diag.to_json(), data.robot), "provenance": prov, **extra}, indent=1,
                         default=float))
    else:
        print(render(diag))
        if exported.left_out:
            print(f"   left out of the exported model (confirmed on no other session): {', '.join(exported.left_out)}")
        if args.out:
            print(f"\nmodel: {args.out} (" + (", ".join(exported.kept) or "geometry only") + ")")
        if args.report:
            print(f"\nreport: {args.report}/index.html")
    return 0
