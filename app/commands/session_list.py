"""``robocal sessions DB...``: what a session database holds (status, steps per procedure), read-only."""
from __future__ import annotations

NAME = "sessions"
HELP = "list session databases: status and steps per procedure"
EXAMPLES = """\
robocal sessions cell.db robocal-demo.db
"""


def add_arguments(p):
    p.add_argument("db", nargs="+", help="session databases")


def run(args) -> int:
    from acq.session.store import connect_readonly
    from calib.errors import RobocalError
    for path in args.db:
        conn = connect_readonly(path)
        try:
            row = conn.execute(
                "SELECT guid, title, coalesce(exit_status, 'running or interrupted'), created_unix_s FROM session"
            ).fetchone()
            if row is None:
                raise RobocalError(f"{path}: holds no session (a database left by a crash while it was created)")
            guid, title, status, created = row
            print(f"{path}: {title} [{guid}] {status}")
            for proc, n, sk in conn.execute("SELECT procedure, count(*), sum(status='skipped') FROM step "
                                            "GROUP BY procedure ORDER BY min(seq)"):
                print(f"  {proc:16s} {n:4d} steps ({sk} skipped)")
        finally:
            conn.close()
    return 0
