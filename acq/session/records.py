"""What was done, per procedure, read from a session database (read-only): steps accepted and skipped, repeats, checks
that failed and what the operator chose then, the instruments and their stated noise.  The report says this next to
every result, because an estimate means little without how it was measured."""
from __future__ import annotations

import json
from dataclasses import dataclass, field

from calib.errors import RobocalError

from .store import connect_readonly


@dataclass
class ProcedureRecord:
    procedure: str
    accepted: int = 0
    skipped: int = 0
    repeats: int = 0                         # attempts beyond the first, over all steps
    failed_checks: int = 0                   # checks that failed on the attempt the operator accepted
    accepted_with_failed: list[str] = field(default_factory=list)     # step keys accepted despite a failed check
    notes: list[str] = field(default_factory=list)


@dataclass
class SessionRecord:
    created_unix_s: float | None
    operator: str
    devices: list[dict]
    procedures: dict[str, ProcedureRecord]
    setup: dict = field(default_factory=dict)


def session_record(path: str) -> SessionRecord:
    """Counts per procedure and the instruments, from ``path`` (read-only)."""
    try:
        conn = connect_readonly(path)
    except Exception as exc:                   # noqa: BLE001 - the caller reports the record as unavailable
        raise RobocalError(f"{path}: cannot read the session record: {exc}") from None
    try:
        row = conn.execute("SELECT session_id, created_unix_s, operator, setup_json FROM session ORDER BY "
                           "session_id LIMIT 1").fetchone()
        if row is None:
            raise RobocalError(f"{path}: holds no session")
        sid, created, operator, setup_json = row
        try:
            setup = json.loads(setup_json or "{}")
        except ValueError:
            setup = {}
        procs: dict[str, ProcedureRecord] = {}
        for step_id, key, proc, status, attempts, note in conn.execute(
                "SELECT step_id, key, procedure, status, attempts, note FROM step WHERE session_id=? ORDER BY seq",
                (sid,)):
            rec = procs.setdefault(proc, ProcedureRecord(proc))
            if status == "accepted":
                rec.accepted += 1
            else:
                rec.skipped += 1
            rec.repeats += max(int(attempts) - 1, 0)
            failed = conn.execute("SELECT COUNT(*) FROM check_result WHERE step_id=? AND attempt=? AND passed=0",
                                  (step_id, attempts)).fetchone()[0]
            rec.failed_checks += failed
            if failed and status == "accepted":
                rec.accepted_with_failed.append(key)
            if note:
                rec.notes.append(f"{key}: {note}")
        devices = []
        for role, driver, url, ident in conn.execute("SELECT role, driver, url, identity_json FROM device "
                                                     "WHERE session_id=?", (sid,)):
            try:
                identity = json.loads(ident or "{}")
            except ValueError:
                identity = {}
            devices.append({"role": role, "driver": driver, "url": url, "identity": identity})
        return SessionRecord(created, operator, devices, procs, setup if isinstance(setup, dict) else {})
    finally:
        conn.close()
