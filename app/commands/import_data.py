"""``robocal import FILE.csv --db NEW.db``: a raw-readings CSV or a pose CSV becomes a session to reprocess.

The database is built in ``NEW.db.importing`` and appears as ``NEW.db`` only when complete; ``--resume`` continues an
interrupted import."""
from __future__ import annotations

import sys

from acq.argtypes import output_file

NAME = "import"
HELP = "import raw readings or pose measurements (CSV) measured with other tools into a new session database"
EXAMPLES = """\
robocal import poses.csv --db imported.db        # data measured with other tools becomes a session
robocal import readings.csv --db copy.db --resume
"""


def add_arguments(p):
    p.add_argument("file", help="raw-readings CSV (has hz_deg) or pose CSV (has q1..q6, x, y, z)")
    p.add_argument("--db", type=output_file, required=True, help="new session database")
    p.add_argument("--setup", metavar="JSON", help="setup geometry (ruler, tool targets ...); default: the demo's")
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted import of the same FILE (kept in DB.importing until complete)")


def run(args) -> int:
    from offline.exchange import import_file
    kind, n = import_file(args.file, args.db, args.setup, resume=args.resume)
    print(f"{args.file}: {n} {kind} steps -> {args.db}; process with: robocal reprocess {args.db}", file=sys.stderr)
    return 0
