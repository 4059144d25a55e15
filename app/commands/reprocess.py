"""``robocal reprocess SESSION.db``: rerun the whole calibration from a saved session with today's code.

The session is opened read-only; results go to ``--json`` / ``--report`` (and, with ``--store``, a provenance row in
the session's ``result`` table: raw data is never rewritten).
"""
from __future__ import annotations

import sys

from acq.argtypes import int_range, output_dir, output_file
from app.commands.demo import add_report_options, check_pdf_options

NAME = "reprocess"
HELP = "rerun the calibration from a saved session (read-only), write JSON estimates and an HTML report"
EXAMPLES = """\
robocal reprocess cell.db --report report/ --json results.json
robocal reprocess cell.db --report report/ --pdf --tolerance-mm 0.5
robocal reprocess cell.db --mc 200              # Monte Carlo errors as well
"""


def add_arguments(p):
    p.add_argument("session", help="session database (.db)")
    p.add_argument("--json", type=output_file, metavar="OUT", help="estimates JSON ('-' for stdout)")
    p.add_argument("--report", type=output_dir, metavar="DIR", help="directory for report.html, results.json, robot.json")
    p.add_argument("--mc", type=int_range(0, 100000), default=0, help="Monte Carlo draws for the estimation errors (0: GUM only)")
    p.add_argument("--store", action="store_true", help="also record the result (with provenance) in the session")
    add_report_options(p)
    p.add_argument("--out-urdf", type=output_file, metavar="FILE.urdf",
                   help="write the calibrated description as a URDF (see robocal identify --out-urdf) and "
                        "FILE.side.json with what a URDF cannot hold")
    p.add_argument("--out-dh-deltas", type=output_file, metavar="FILE.csv",
                   help="write per joint the identified change of theta, d, a, alpha (and beta) with 1 sigma "
                        "(DH descriptions; see robocal identify --out-dh-deltas)")
    p.add_argument("--diagnose", action="store_true",
                   help="also diagnose the sim-to-real gap of the pose set (robocal diagnose on this session) and "
                        "put it in the summary, the JSON (key diagnosis) and the report")


def session_diagnosis(db: str) -> dict:
    """The diagnosis of a session's pose set (the same as ``robocal diagnose DB --json``), for the report."""
    from offline.exchange import pose_arrays, session_robot
    from calib.diagnose import diagnose
    from calib.diagnose.data import from_session_arrays
    from calib.names import with_joint_names
    arrays = pose_arrays(str(db))
    robot = session_robot(str(db))
    return with_joint_names(diagnose(from_session_arrays(robot, arrays, str(db))).to_json(), robot)


def _session_model(db: str, res: dict, option: str):
    """The pose set's identified model of a reprocessed session, its 1-sigma errors and estimated parameters, and
    the URDF its set-up's description comes from (None for a DH description)."""
    import numpy as np
    from app.reprocess import load_session
    from calib.compensate import model_from_document
    from calib.errors import RobocalError
    from calib.export.urdf_out import urdf_source
    if not res.get("robot"):
        raise RobocalError(f"{db}: {option}: the pose set gave no identified robot "
                           f"({'; '.join(res.get('problems') or ['no pose set'])})")
    im = model_from_document(res["robot"], f"{db}: robot")
    params = res["robot"]["parameters"]
    errors = {p["name"]: p.get("error") or 0.0 for p in params}
    sigma = np.array([errors.get(n, 0.0) for n in im.model.names], float)
    free = {p["name"] for p in params if p.get("estimated")}
    setup = load_session(db).setup
    source = urdf_source(setup.robot or None, setup.base_link or None, setup.tip_link or None)
    return im, sigma, free, source


def session_urdf(db: str, res: dict, out: str):
    """The calibrated URDF of a reprocessed session: its pose set's identified robot, checked on the set's poses."""
    from offline.exchange import pose_arrays
    from calib.export.write import write_calibrated_urdf
    im, sigma, _, source = _session_model(db, res, "--out-urdf")
    return write_calibrated_urdf(out, source, im.model, im.theta, sigma, pose_arrays(db)["q_rad"],
                                 f"robocal reprocess {db}")


def session_dh_deltas(db: str, res: dict, out: str) -> str:
    from calib.export.dh_deltas import write_dh_deltas
    im, sigma, free, source = _session_model(db, res, "--out-dh-deltas")
    write_dh_deltas(out, im.model, im.theta, sigma, free, source)
    return f"DH deltas written: {out}"


def run(args) -> int:
    from app.commands.demo import _summary, _write_json
    from app.reprocess import reprocess
    from acq.session.store import save_result

    check_pdf_options(args)
    res = reprocess(args.session, n_mc=args.mc)
    if args.diagnose:
        res["diagnosis"] = session_diagnosis(args.session)
    if args.json:
        _write_json(res, args.json)
    if args.json != "-":
        _summary(res, args.verbose, args.tolerance_mm)
    lines = session_urdf(args.session, res, args.out_urdf).lines() if args.out_urdf else []
    if args.out_dh_deltas:
        lines.append(session_dh_deltas(args.session, res, args.out_dh_deltas))
    for line in lines:
        print(line, file=sys.stderr if args.json == "-" else sys.stdout)
    if args.report:
        from offline.report import write_report
        write_report(res, args.report, tolerance_mm=args.tolerance_mm, pdf=args.pdf)
    if args.store:
        save_result(args.session, res["session"]["guid"], "robocal reprocess", {"n_mc": args.mc},
                    {k: v for k, v in res.items() if k != "figures"})
    return 0
