"""``robocal identify``: identify the robot from a pose-measurement CSV (joint readings + measured tool points)."""
from __future__ import annotations

import copy
import json
import sys

from calib.errors import RobocalError
from acq.argtypes import add_force_argument, add_robot_argument, effect_spec, output_file, positive_float, positive_int

from app.commands._csvargs import add_unit_arguments, units
from app.commands.diagnose import add_outlier_arguments

NAME = "identify"
HELP = "identify geometry (and running errors) from a pose-measurement CSV"
EXAMPLES = """\
robocal identify poses.csv --thesis-effects --out model.json --out-robot identified.toml
robocal identify poses.csv --effect transmission_error:4:0.9 --effect backlash:2
"""


def add_arguments(p):
    p.add_argument("data", metavar="DATA.csv", help="pose CSV: q1..q6 (deg), x, y, z (mm) and optional conditions")
    add_robot_argument(p)
    p.add_argument("--noise-mm", type=positive_float, default=None,
                   help="1-sigma point noise per coordinate (mm), used when the file has no sigma_*_mm columns; "
                        "without either the noise is estimated from the data (repeats, several targets) or, when "
                        "they cannot tell, the errors are scaled by the fit's residual (said in the output)")
    p.add_argument("--select", choices=("auto", "all"), default="auto",
                   help="auto (default): estimate only the parameters the data determine (significant at 2 sigma "
                        "and improving the leave-one-pose-out prediction), holding the rest at their design values "
                        "or priors; all: estimate the whole free set")
    p.add_argument("--effect", type=effect_spec, action="append", default=[], metavar="SPEC",
                   help="running error to identify, e.g. transmission_error:4:0.9, joint_compliance:3, "
                        "backlash:2, cross_coupling:6:5, link_compliance:2, thermal_drift (repeatable)")
    p.add_argument("--thesis-effects", action="store_true",
                   help="identify the running errors the thesis measured (TE 4 and 6, compliance 3 and 4, "
                        "coupling 5->6)")
    p.add_argument("--out", type=output_file, metavar="MODEL.json", help="write every parameter with its uncertainty")
    p.add_argument("--out-robot", type=output_file, metavar="ROBOT.toml", help="write the identified robot description")
    p.add_argument("--out-urdf", type=output_file, metavar="FILE.urdf",
                   help="write the description as a calibrated URDF (corrected joint origins, every other element "
                        "kept; a DH description gets a URDF made from its frames) and FILE.side.json with what a "
                        "URDF cannot hold; the file is read back and checked against the model")
    p.add_argument("--out-dh-deltas", type=output_file, metavar="FILE.csv",
                   help="write per joint the identified change of theta, d, a, alpha (and beta) with 1 sigma: the "
                        "form a controller takes (DH descriptions)")
    p.add_argument("--json", action="store_true", help="print the model document as JSON")
    add_outlier_arguments(p)
    add_unit_arguments(p)
    add_force_argument(p)
    p.add_argument("--polar-noise", metavar="ARCSEC,MM[,PPM]",
                   help="noise of hz_deg/v_deg/dist_mm rows (laser tracker, total station): angle 1-sigma in arc "
                        "seconds, distance 1-sigma in mm, plus ppm of the distance (default 1,0.01,1)")
    p.add_argument("--orientation-noise-deg", type=positive_float, default=0.01, metavar="DEG",
                   help="1-sigma noise per axis of rx_deg/ry_deg/rz_deg rows (a 6-D tracker probe; R = Rz(rz) "
                        "Ry(ry) Rx(rx), the measured frame in the instrument frame), default 0.01")
    p.add_argument("--free", action="append", default=[], metavar="PATTERN",
                   help="estimate only the parameters matching these shell patterns (comma-separated or repeated; "
                        "joint names allowed: 'base.*,tool.*,arm_*_joint.a_mm'); the rest keep their design values")
    p.add_argument("--prior", action="append", default=[], metavar="NAME=VALUE±SIGMA",
                   help="a prior on one parameter (unit of its name; *_deg for angles in degrees); the "
                        "description's [tolerances] are priors around the design values already; an effect's "
                        "parameter starts at its prior")
    p.add_argument("--starts", type=positive_int, default=1, metavar="N",
                   help="refit from N-1 further starts around the estimate and say whether they land on the same "
                        "estimate, or which parameters the data leave open (default 1: no check)")


def run(args) -> int:
    import numpy as np
    from calib.compensate import model_document, save_model
    from calib.effects import THESIS_RUNNING_ERRORS, effect_from_text
    from calib.effects.mass_moment import check_scale
    from calib.evaluation import data_rows, fit_rows, split_metrics, station_names, station_start, with_polar_points
    from calib.orientation import with_orientation_points
    from calib.rows import context_of, point_covariance
    from calib.polar import PolarNoise
    from calib.identify import PointObservations, check_drivers, default_free
    from calib.priors import free_from_patterns, priors_for
    from calib.model import MeasurementModel
    from calib.posecsv import read_pose_csv
    from calib.provenance import provenance
    from calib.loading import load_robot
    from calib.units import DEG

    robot = load_robot(args.robot)
    full = read_pose_csv(args.data, robot.n, robot.prismatic, robot=robot, **units(args))
    full = with_polar_points(full, PolarNoise.from_text(args.polar_noise) if args.polar_noise else None)
    measured = full                              # the rows as measured: what the held-out figures are about
    weight_mm = args.noise_mm if args.noise_mm is not None else 1.0      # relative weights until the noise is known
    full, robot = with_orientation_points(full, robot, weight_mm, args.orientation_noise_deg * DEG)
    table, robot, target_offsets = fit_rows(full, robot)
    if table.points_mm is None:
        raise RobocalError(f"{args.data}: columns x, y, z (measured tool points, mm) are needed to identify")
    if args.noise_mm is not None and not args.noise_mm > 0:
        raise RobocalError(f"identify: --noise-mm must be positive, got {args.noise_mm}")
    specs = list(args.effect) + (list(THESIS_RUNNING_ERRORS) if args.thesis_effects else [])
    effects = [effect_from_text(s, robot.n, robot) for s in specs]
    model = MeasurementModel(robot, effects + target_offsets, stations=station_names(full))
    ctx = context_of(model, table)
    cov = point_covariance(table)
    obs = PointObservations(table.q_rad, table.points_mm, cov, sigma_mm=weight_mm, ctx=ctx)
    free = free_from_patterns(model, args.free) if args.free else None
    priors = priors_for(model, args.prior, free or default_free(model))
    # the rigid-fit start moves the base: only when the whole base is estimated (else it keeps its design value)
    start = free is None or all(n in free for n in model.names if n.startswith("base."))
    from calib.plausibility import check_data, check_fit, enforce
    implausible = enforce(check_data(MeasurementModel(robot), table.q_rad, table.points_mm, args.data,
                                     n_free=len(free or default_free(model)), ignored_columns=full.ignored_columns,
                                     prismatic=robot.prismatic, target=table.target), args.force_implausible,
                                     "identify")
    check_scale(model, ctx, priors, args.data)
    check_drivers(model, obs, args.data)
    theta0 = None
    if table.station is not None and len(set(table.station)) > 1:
        theta0, start = station_start(model, table), False        # each set-up placed by its own rigid fit
    fit = _Fit(model, free or default_free(model), priors, theta0, start, args.outliers, args.loss, args.select,
               table.pose_id)
    weights = _weights(args, table, obs, fit, measured)
    obs = weights.obs
    sel, first = fit.select(obs)
    ident = sel.ident
    if first.outlier_report is not None:       # flagged poses named as the file numbers them (rows, pose ids)
        first.outlier_report.numbered(*data_rows(measured, table))
        ident.outlier_report = first.outlier_report
    held_out = split_metrics(model, ident.theta[:model.P], measured) if full.split is not None else {}
    try:
        heldout = _heldout(fit, sel, measured, obs, weights, table).as_dict()
    except RobocalError as exc:          # folds too small to fit what the whole set can: said, not guessed
        heldout = {"before": None, "after": None, "uncertainty": None,
                   "heldout_protocol": f"not measured: a 5-fold split leaves too few poses per fold ({exc})"}
    implausible += enforce(check_fit(ident.reduced_chi2, args.data), args.force_implausible, "identify")
    noise = _noise(args, measured, obs, ident, weights, model.robot.tool_point_frames or None)
    orientation = _orientation(args, model, ident.theta[:model.P], measured)
    fit_mask = measured.split_mask("fit") if measured.split is not None else np.ones(measured.n, bool)
    n_rows = int(fit_mask.sum())
    n_poses = len(set(np.asarray(measured.pose_id)[fit_mask])) if measured.pose_id else n_rows
    checks = _checks(args, model, obs, ident, priors)
    prov = provenance(args.robot)
    from calib.heldout import noise_scale
    extra = {"located_nominal": dict(zip(model.names, map(float, sel.located.ident.theta[: model.P]))),
             "prediction_noise": {"sigma_mm": float(weights.sigma_mm), "scale": noise_scale(ident)}}
    if args.out:
        save_model(args.out, model, ident, args.out_robot, provenance=prov, extra=extra)
    elif args.out_robot:
        from calib.compensate import robot_from_theta
        from calib.robot import robot_to_toml
        from calib.fileio import atomic_write_text
        atomic_write_text(args.out_robot, robot_to_toml(robot_from_theta(model, ident.theta)))
    exported = _exports(args, model, ident, table)
    from calib.fitreport import chi2_words, noise_line
    if args.json:
        warn = {"plausibility_warnings": implausible} if implausible else {}
        if exported:
            warn["exported"] = {k: v for k, v in exported.items() if k != "lines"}
        if orientation:
            warn["orientation"] = orientation
        print(json.dumps({**model_document(model, ident, provenance=prov, extra=extra), **held_out,
                          **heldout, **warn, "n_poses": n_poses, "n_points": n_rows,
                          "selection": sel.as_dict(), "noise": weights.as_dict(ident),
                          "reduced_chi2_words": chi2_words(ident, weights.given, noise),
                          "noise_estimated_mm": noise.estimated_mm, "noise_estimate": noise.as_dict(),
                          **checks.as_dict()}, indent=1))
        return 0
    from calib.accuracy import before_after_line
    print(f"robocal identify {args.data}: " + (before_after_line(heldout) if heldout["after"] else
                                                 f"accuracy on held-out rows {heldout['heldout_protocol']}"))
    print(f"  {n_poses} poses" + (f" ({n_rows} points)" if n_rows != n_poses else "") + f", {len(ident.free)} parameters estimated, residual RMS {ident.residual_rms:.4f} mm "
          f"(a fit residual, not the accuracy), reduced chi-square {ident.reduced_chi2:.2f}")
    print("  " + noise_line(weights.as_dict(ident)))
    words = chi2_words(ident, weights.given, noise)
    if words:
        print("  " + words)
    if held_out:
        print(f"  data's own split: {held_out['n_fit']} fit rows (RMS {held_out['fit_rms_mm']:.4f} mm), "
              f"{held_out['n_test']} test rows: RMS {held_out['test_rms_mm']:.4f} mm, max {held_out['test_max_mm']:.4f} mm")
    if orientation:
        o = orientation
        print(f"  orientation: {o['statement']}")
        print(f"  orientation error (geodesic): fit rows mean {o['fit']['mean_deg']:.4f} deg, max "
              f"{o['fit']['max_deg']:.4f} deg" + (f"; test rows mean {o['test']['mean_deg']:.4f} deg, max "
                                                  f"{o['test']['max_deg']:.4f} deg" if o.get("test") else ""))
    u = heldout["uncertainty"] or {}
    if u.get("median_abs_z") is not None:
        print(f"  predicted sigma of the held-out points: median |error|/sigma {u['median_abs_z']:.2f} (0.67 when "
              f"honest), {100 * u['within_2sigma']:.0f} % within 2 sigma (95 % when honest)")
    if noise.estimated_mm is not None and weights.given:
        print(f"  noise per coordinate: given {noise.given_mm:.4f} mm, from the data {noise.estimated_mm:.4f} mm "
              f"({noise.how})")
    if weights.given:               # (not given: the noise line above already says why a source was set aside)
        for line in noise.set_aside_lines():
            print("  " + line)
    for line in sel.lines(robot):
        print("  " + line)
    for line in first.identifiability.report(robot):
        print("  " + line)
    for line in ident.outlier_report.lines():
        print("  " + line)
    _parameter_table(ident, robot)
    for line in checks.lines():
        print("  " + line)
    if args.out:
        print(f"  written: {args.out}" + (f", {args.out_robot}" if args.out_robot else ""))
    for line in exported.get("lines", []):
        print("  " + line)
    return 0


def _orientation(args, model, theta, measured) -> dict:
    """How 6-D rows were used and how well the fit reproduces their orientations (geodesic angles, fit and test
    rows); {} without orientation columns."""
    from calib import orientation as ori
    if measured.orientation_rad is None:
        return {}
    out = {"statement": ori.statement(args.orientation_noise_deg), "convention": ori.CONVENTION,
           "noise_deg": args.orientation_noise_deg, "lever_mm": ori.LEVER_MM}
    for part in ("fit", "test"):
        rows = measured.split_mask(part) if measured.split is not None else None
        if rows is None and part == "test":
            continue
        sub = measured if rows is None else measured.subset(rows)
        if sub.n:
            out[part] = ori.summary_deg(ori.orientation_errors_deg(model, theta, sub))
    return out


def _exports(args, model, ident, table) -> dict:
    """``--out-urdf`` and ``--out-dh-deltas``: the files, and what the terminal and the JSON say about them."""
    out: dict = {}
    sigma = ident.sigma[: model.P]
    theta = ident.theta[: model.P]
    if args.out_urdf:
        from calib.export.urdf_out import urdf_source
        from calib.export.write import write_calibrated_urdf
        exp = write_calibrated_urdf(args.out_urdf, urdf_source(args.robot), model, theta, sigma, table.q_rad,
                                    f"robocal identify {args.data}")
        out.update(urdf=exp.urdf, side_file=exp.side, urdf_check_max_mm=exp.check_mm, urdf_check_poses=exp.n_poses)
        out.setdefault("lines", []).extend(exp.lines())
    if args.out_dh_deltas:
        from calib.export.dh_deltas import write_dh_deltas
        from calib.export.urdf_out import urdf_source
        write_dh_deltas(args.out_dh_deltas, model, theta, sigma, set(ident.free), urdf_source(args.robot))
        out["dh_deltas"] = str(args.out_dh_deltas)
        out.setdefault("lines", []).append(f"DH deltas written: {args.out_dh_deltas}")
    return out


def _parameter_table(ident, robot) -> None:
    """The estimated parameters, joints named and angles in degrees (the names --free and --prior read back); a
    parameter on a direction the data do not determine is named with that direction instead of a number."""
    from calib import names as naming
    undetermined = ident.undetermined_names()
    print(f"  {'parameter':<44}{'value':>14}{'1 sigma':>12}  unit")
    for name in ident.free:
        shown, v, s, unit = naming.edge(name, ident.value(name), ident.std(name), robot)
        sd = f"{s:>12.3g}" if name not in undetermined else f"{'undetermined':>12}"
        print(f"  {shown:<44}{v:>14.6g}{sd}  {unit}")
    for c in ident.undetermined:
        print(f"  not determined by these data (no sigma given): {naming.prose(c.words(), robot)}")
    corr = ident.correlations(0.9)
    if corr:
        print("  correlations above 0.9: " + "; ".join(f"{naming.edge_name(a, robot)} ~ {naming.edge_name(b, robot)} "
                                                        f"({r:+.3f})" for a, b, r in corr))


class _Fit:
    """How this identify call fits any set of rows: the same free set, priors, start, outlier mode, loss and
    selection rule for the final fit and for every cross-validation fold (so each fold repeats every choice)."""

    def __init__(self, model, free, priors, theta0, start, outliers, loss, rule, pose_id=None):
        self.model, self.free, self.priors, self.theta0 = model, free, priors, theta0
        self.start, self.outliers, self.loss, self.rule = start, outliers, loss, rule
        self.error_scale = "inflate"
        self.pose_id = list(pose_id) if pose_id else None      # rows of one pose: held out together

    def select(self, obs, explain: bool = True, warm=None, rows=None):
        """The selection on ``obs``: every row, or the rows ``rows`` of the fitted table (a fold)."""
        from calib.selection import select
        groups = None if self.pose_id is None else (self.pose_id if rows is None else [self.pose_id[i] for i in rows])
        return select(self.model, obs, self.free, self.priors, self.theta0, self.start, self.outliers, self.loss,
                      rule=self.rule, error_scale=self.error_scale, explain=explain, warm=warm, groups=groups)


def _heldout(fit: _Fit, sel, measured, obs, weights, table):
    """Before/after on held-out rows: the data's test rows (the fit saw none of them), else k-fold predictions in
    which every fold repeats the whole choice on its own rows."""
    import numpy as np
    from calib.heldout import crossval, predict_heldout
    from calib.orientation import orientation_errors_deg
    from calib.rows import context_of, point_covariance

    if measured.split is not None:
        test = measured.subset(measured.split_mask("test"))
        cov = point_covariance(test)
        if cov is None:
            cov = np.broadcast_to(np.eye(3) * weights.sigma_mm ** 2, (test.n, 3, 3))
        out = predict_heldout(fit.model, sel.located.ident.theta, sel.ident, test.q_rad, context_of(fit.model, test),
                              test.points_mm, cov, "the data's own split: test rows, seen once at the end")
        out.before_deg = orientation_errors_deg(fit.model, sel.located.ident.theta, test)
        out.after_deg = orientation_errors_deg(fit.model, sel.ident.theta, test)
        return out

    # a fold repeats every choice that changes its fit; flagging gross errors (the default) changes none, so the
    # folds leave out its robust refit (rejecting them, --outliers reject, is a choice each fold makes again); each
    # fold's fits start from the whole set's (a start point, not a choice: calib.selection.select's ``warm``)
    fold = copy.copy(fit)
    if fit.outliers == "flag":
        fold.outliers = "off"

    def choose(rows, test):
        train_obs, test_obs = weights.fold(rows, test)      # the noise decided again on the fold's rows
        s, _ = fold.select(train_obs, explain=False, warm=sel, rows=rows)
        return s.located.ident.theta, s.ident, test_obs
    return crossval(fit.model, obs, choose, 5, table.pose_id or None)


def _weights(args, table, obs, fit: _Fit, measured):
    """The points' noise: given (sigma columns, polar noise, --noise-mm), else estimated from the data without a
    model (repeats, several targets per pose), else unknown: then the relative weights are kept, their scale set to
    the fit's robust residual scale, and the errors scaled by the residual (``error_scale="residual"``)."""
    from calib.fitreport import Weights
    return Weights.decide(table, obs, args.noise_mm, fit, measured)


class _Checks:
    """What the estimate itself says about its trust: negative compliances or masses (calib.physical) and, with
    --starts, whether other starts land on it (calib.starts)."""

    def __init__(self, signs: list[dict], starts=None):
        self.signs, self.starts = signs, starts

    def lines(self) -> list[str]:
        from calib.physical import sign_lines
        return sign_lines(self.signs) + (self.starts.lines() if self.starts is not None else [])

    def as_dict(self) -> dict:
        out = {"sign_findings": self.signs} if self.signs else {}
        return {**out, **({"starts": self.starts.as_dict()} if self.starts is not None else {})}


def _checks(args, model, obs, ident, priors) -> _Checks:
    from calib.physical import sign_findings
    from calib.starts import check_starts
    starts = check_starts(model, obs, ident, args.starts, priors, args.loss) if args.starts > 1 else None
    return _Checks(sign_findings(model, ident), starts)


def _noise(args, measured, obs, ident, weights, body: dict | None = None):
    """The noise the data show (calib.noise, shared with diagnose) against the given one; the one-line warning on
    stderr when they disagree by more than 1.5x.  Without a model-free source the bound is the fit's residual with
    its degrees of freedom (the given sigma times the square root of the reduced chi-square) -- the test rows of a
    split are not looked at: they are seen once, for the held-out figures."""
    import numpy as np
    from calib import noise as est

    bound, how = est.given_sigma_mm(obs.cov_mm2) * np.sqrt(ident.reduced_chi2), "fit residual (upper bound)"
    fit_rows = measured.subset(measured.split_mask("fit")) if measured.split is not None else measured
    n = est.for_rows(fit_rows, weights.sigma_mm, bound, how, body=body, given=weights.given)
    if weights.given:
        line = n.warning(f"robocal identify {args.data}", "the parameters' error bars assume the given noise: give "
                                                           "--noise-mm (or the sigma columns) as the data show it")
        if line:
            print(f"warning: {line}", file=sys.stderr)
    return n
