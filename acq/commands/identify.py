"""``robocal identify``: identify the robot from a pose-measurement CSV (joint readings + measured tool points)."""
from __future__ import annotations

import json
import sys

from calib.errors import RobocalError
from acq.argtypes import add_force_argument, effect_spec, output_file, positive_float, positive_int

from ._csvargs import add_unit_arguments, units
from .diagnose import add_outlier_arguments

NAME = "identify"
HELP = "identify geometry (and running errors) from a pose-measurement CSV"


def add_arguments(p):
    p.add_argument("data", metavar="DATA.csv", help="pose CSV: q1..q6 (deg), x, y, z (mm) and optional conditions")
    p.add_argument("--robot", metavar="FILE", help="robot description TOML (default: the thesis's Puma 560)")
    p.add_argument("--noise-mm", type=positive_float, default=0.05,
                   help="1-sigma point noise per coordinate (mm), used when the file has no sigma_*_mm columns")
    p.add_argument("--effect", type=effect_spec, action="append", default=[], metavar="SPEC",
                   help="running error to identify, e.g. transmission_error:4:0.9, joint_compliance:3, "
                        "backlash:2, cross_coupling:6:5, link_compliance:2, thermal_drift (repeatable)")
    p.add_argument("--thesis-effects", action="store_true",
                   help="identify the running errors the thesis measured (TE 4 and 6, compliance 3 and 4, "
                        "coupling 5->6)")
    p.add_argument("--out", type=output_file, metavar="MODEL.json", help="write every parameter with its uncertainty")
    p.add_argument("--out-robot", type=output_file, metavar="ROBOT.toml", help="write the identified robot description")
    p.add_argument("--json", action="store_true", help="print the model document as JSON")
    add_outlier_arguments(p)
    add_unit_arguments(p)
    add_force_argument(p)
    p.add_argument("--polar-noise", metavar="ARCSEC,MM[,PPM]",
                   help="noise of hz_deg/v_deg/dist_mm rows (laser tracker, total station): angle 1-sigma in arc "
                        "seconds, distance 1-sigma in mm, plus ppm of the distance (default 1,0.01,1)")
    p.add_argument("--orientation-noise-deg", type=positive_float, default=0.01, metavar="DEG",
                   help="1-sigma noise of rx_deg/ry_deg/rz_deg rows (a 6-D tracker probe), default 0.01")
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
    from calib.compensate import model_document, save_model, unit_of
    from calib.effects import THESIS_RUNNING_ERRORS, effect_from_text
    from calib.effects.mass_moment import check_scale
    from calib.evaluation import (context_of, data_rows, fit_rows, point_covariance, split_metrics, station_names,
                                  station_start, with_orientation_points, with_polar_points)
    from calib.polar import PolarNoise
    from calib.identify import PointObservations, check_drivers, default_free, identify
    from calib.priors import free_from_patterns, priors_for
    from calib.model import MeasurementModel
    from calib.posecsv import read_pose_csv
    from calib.provenance import provenance
    from calib.robot import load_robot
    from calib.units import DEG

    robot = load_robot(args.robot)
    full = read_pose_csv(args.data, robot.n, robot.prismatic, robot=robot, **units(args))
    full = with_polar_points(full, PolarNoise.from_text(args.polar_noise) if args.polar_noise else None)
    measured = full                              # the rows as measured: what the held-out figures are about
    full, robot = with_orientation_points(full, robot, args.noise_mm, args.orientation_noise_deg * DEG)
    table, robot, target_offsets = fit_rows(full, robot)
    if table.points_mm is None:
        raise RobocalError(f"{args.data}: columns x, y, z (measured tool points, mm) are needed to identify")
    if not args.noise_mm > 0:
        raise RobocalError(f"identify: --noise-mm must be positive, got {args.noise_mm}")
    specs = list(args.effect) + (list(THESIS_RUNNING_ERRORS) if args.thesis_effects else [])
    effects = [effect_from_text(s, robot.n) for s in specs]
    model = MeasurementModel(robot, effects + target_offsets, stations=station_names(full))
    ctx = context_of(model, table)
    cov = point_covariance(table)
    obs = PointObservations(table.q_rad, table.points_mm, cov, sigma_mm=args.noise_mm, ctx=ctx)
    free = free_from_patterns(model, args.free) if args.free else None
    priors = priors_for(model, args.prior, free or default_free(model))
    # the rigid-fit start moves the base: only when the whole base is estimated (else it keeps its design value)
    start = free is None or all(n in free for n in model.names if n.startswith("base."))
    from calib.plausibility import check_data, check_fit, enforce
    implausible = enforce(check_data(MeasurementModel(robot), table.q_rad, table.points_mm, args.data,
                                     n_free=len(free or default_free(model)), ignored_columns=full.ignored_columns,
                                     prismatic=robot.prismatic), args.force_implausible, "identify")
    check_scale(model, ctx, priors, args.data)
    check_drivers(model, obs, args.data)
    theta0 = None
    if table.station is not None and len(set(table.station)) > 1:
        theta0, start = station_start(model, table), False        # each set-up placed by its own rigid fit
    ident = identify(model, obs, free=free, priors=priors, start=start, theta0=theta0, outliers=args.outliers,
                     loss=args.loss)
    if ident.outlier_report is not None:       # flagged poses named as the file numbers them (rows, pose ids)
        ident.outlier_report.numbered(*data_rows(measured, table))
    held_out = split_metrics(model, ident.theta[:model.P], measured) if full.split is not None else {}
    implausible += enforce(check_fit(ident.reduced_chi2, args.data), args.force_implausible, "identify")
    noise = _noise(args, measured, obs, ident, held_out, model.robot.tool_point_frames or None)
    checks = _checks(args, model, obs, ident, priors)
    prov = provenance(args.robot)
    if args.out:
        save_model(args.out, model, ident, args.out_robot, provenance=prov)
    elif args.out_robot:
        from calib.compensate import robot_from_theta
        from calib.robot import robot_to_toml
        from calib.fileio import atomic_write_text
        atomic_write_text(args.out_robot, robot_to_toml(robot_from_theta(model, ident.theta)))
    if args.json:
        extra = {"plausibility_warnings": implausible} if implausible else {}
        print(json.dumps({**model_document(model, ident, provenance=prov), **held_out, **extra,
                          "noise_estimated_mm": noise.estimated_mm, "noise_estimate": noise.as_dict(),
                          **checks.as_dict()}, indent=1))
        return 0
    print(f"robocal identify {args.data}: {table.n} poses, {len(ident.free)} parameters estimated, "
          f"residual RMS {ident.residual_rms:.4f} mm, reduced chi-square {ident.reduced_chi2:.2f}")
    if held_out:
        print(f"  data's own split: {held_out['n_fit']} fit rows (RMS {held_out['fit_rms_mm']:.4f} mm), "
              f"{held_out['n_test']} test rows: RMS {held_out['test_rms_mm']:.4f} mm, max {held_out['test_max_mm']:.4f} mm")
    if noise.estimated_mm is not None:
        print(f"  noise per coordinate: given {noise.given_mm:.4f} mm, from the data {noise.estimated_mm:.4f} mm "
              f"({noise.how})")
    for line in ident.identifiability.report(robot.description_joint_names):
        print("  " + line)
    for line in ident.outlier_report.lines():
        print("  " + line)
    print(f"  {'parameter':<44}{'value':>14}{'1 sigma':>12}  unit")
    for name in ident.free:
        v, s = ident.value(name), ident.std(name)
        unit = unit_of(name)
        if unit == "rad":           # shown in degrees under the name that says so (what --prior reads back)
            v, s, unit = v / DEG, s / DEG, "deg"
            name = name[: -len("_rad")] + "_deg" if name.endswith("_rad") else name
        print(f"  {name:<44}{v:>14.6g}{s:>12.3g}  {unit}")
    corr = ident.correlations(0.9)
    if corr:
        print("  correlations above 0.9: " + "; ".join(f"{a} ~ {b} ({r:+.3f})" for a, b, r in corr))
    for line in checks.lines():
        print("  " + line)
    if args.out:
        print(f"  written: {args.out}" + (f", {args.out_robot}" if args.out_robot else ""))
    return 0


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


def _noise(args, measured, obs, ident, held_out: dict, body: dict | None = None):
    """The noise the data show (calib.noise, shared with diagnose) against the given one; the one-line warning on
    stderr when they disagree by more than 1.5x.  Without a model-free source the bound is the held-out residual
    (the data's own split) or the fit's residual with its degrees of freedom (the given sigma times the square
    root of the reduced chi-square)."""
    import numpy as np
    from calib import noise as est

    if held_out.get("test_rms_mm") is not None:
        bound, how = held_out["test_rms_mm"] / np.sqrt(3.0), "held-out residual (upper bound)"
    else:
        bound, how = est.given_sigma_mm(obs.cov_mm2) * np.sqrt(ident.reduced_chi2), "fit residual (upper bound)"
    n = est.for_rows(measured, args.noise_mm, bound, how, body=body)
    line = n.warning(f"robocal identify {args.data}", "the parameters' error bars assume the given noise: give "
                                                       "--noise-mm (or the sigma columns) as the data show it")
    if line:
        print(f"warning: {line}", file=sys.stderr)
    return n
