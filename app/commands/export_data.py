"""``robocal export SESSION.db``: raw readings (CSV or JSON) and pose measurements (pose CSV) for other tools.

Formats are documented in :mod:`offline.exchange` and docs/operator-guide.md.
"""
from __future__ import annotations

import sys
from acq.argtypes import output_file

NAME = "export"
HELP = "export a session's raw readings (CSV/JSON) or its pose measurements (pose CSV)"
EXAMPLES = """\
robocal export cell.db --poses poses.csv --readings readings.csv
robocal export cell.db --json -                  # the whole session as JSON on stdout
"""


def add_arguments(p):
    p.add_argument("session", help="session database")
    p.add_argument("--readings", type=output_file, metavar="CSV", help="raw theodolite readings of accepted steps")
    p.add_argument("--poses", type=output_file, metavar="CSV", help="pose set: encoder joint readings (deg) and tool target (mm)")
    p.add_argument("--json", type=output_file, metavar="OUT", help="the whole session (steps, inputs, readings) as JSON ('-' for stdout)")


def run(args) -> int:
    from calib.errors import RobocalError
    from offline import exchange
    if not (args.readings or args.poses or args.json):
        raise RobocalError("export: say what to write (--readings, --poses and/or --json)")
    if args.readings:
        print(f"{exchange.export_readings_csv(args.session, args.readings)} readings -> {args.readings}",
              file=sys.stderr)
    if args.poses:
        print(f"{exchange.export_poses_csv(args.session, args.poses)} poses -> {args.poses}", file=sys.stderr)
    if args.json:
        exchange.export_json(args.session, args.json)
    return 0
