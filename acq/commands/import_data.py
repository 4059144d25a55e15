"""``robocal import FILE.csv --db NEW.db``: a raw-readings CSV or a pose CSV becomes a session to reprocess."""
from __future__ import annotations

import sys
from acq.argtypes import output_file

NAME = "import"
HELP = "import raw readings or pose measurements (CSV) measured with other tools into a new session database"


def add_arguments(p):
    p.add_argument("file", help="raw-readings CSV (has hz_deg) or pose CSV (has q1..q6, x, y, z)")
    p.add_argument("--db", type=output_file, required=True, help="new session database")
    p.add_argument("--setup", metavar="JSON", help="setup geometry (ruler, tool targets ...); default: the demo's")


def run(args) -> int:
    from acq.session.exchange import import_file
    kind, n = import_file(args.file, args.db, args.setup)
    print(f"{args.file}: {n} {kind} steps -> {args.db}; process with: robocal reprocess {args.db}", file=sys.stderr)
    return 0
