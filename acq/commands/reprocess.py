"""``robocal reprocess SESSION.db``: rerun the whole calibration from a saved session with today's code.

The session is opened read-only; results go to ``--json`` / ``--report`` (and, with ``--store``, a provenance row in
the session's ``result`` table: raw data is never rewritten).
"""
from __future__ import annotations

from acq.argtypes import int_range, output_dir, output_file
from acq.commands.demo import add_report_options, check_pdf_options

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
    p.add_argument("--diagnose", action="store_true",
                   help="also diagnose the sim-to-real gap of the pose set (robocal diagnose on this session) and "
                        "put it in the summary, the JSON (key diagnosis) and the report")


def session_diagnosis(db: str) -> dict:
    """The diagnosis of a session's pose set (the same as ``robocal diagnose DB --json``), for the report."""
    from acq.session.exchange import pose_arrays, session_robot
    from calib.diagnose import diagnose
    from calib.diagnose.data import from_session_arrays
    arrays = pose_arrays(str(db))
    return diagnose(from_session_arrays(session_robot(str(db)), arrays, str(db))).to_json()


def run(args) -> int:
    from acq.commands.demo import _summary, _write_json
    from acq.session.reprocess import reprocess
    from acq.session.store import save_result

    check_pdf_options(args)
    res = reprocess(args.session, n_mc=args.mc)
    if args.diagnose:
        res["diagnosis"] = session_diagnosis(args.session)
    if args.json:
        _write_json(res, args.json)
    if args.json != "-":
        _summary(res, args.verbose, args.tolerance_mm)
    if args.report:
        from acq.session.report import write_report
        write_report(res, args.report, tolerance_mm=args.tolerance_mm, pdf=args.pdf)
    if args.store:
        save_result(args.session, res["session"]["guid"], "robocal reprocess", {"n_mc": args.mc},
                    {k: v for k, v in res.items() if k != "figures"})
    return 0
