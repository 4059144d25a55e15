"""A stored session as the reduction reads it: the session row, its plan and set-up, and every accepted step with the
readings, operator inputs and encoder counts of its accepted (last) attempt.  Opened read-only; every JSON column and
array blob is checked as it is read, so a damaged file is one line naming it."""
from __future__ import annotations

import sqlite3
from dataclasses import dataclass, field, replace

import numpy as np

from calib.errors import RobocalError

from acq.session.setup_file import setup_from_text
from acq.session.setup_types import BenchSetup
from acq.session.store import StoreError, connect_readonly, from_npy, json_column


@dataclass
class SessionData:
    path: str
    session: dict
    plan: dict
    setup: BenchSetup
    steps: list[dict]                               # accepted steps, each with readings, chunks, inputs
    devices: list[dict] = field(default_factory=list)

    @property
    def metadata(self) -> dict:
        """The session's metadata (``emulated``, ``scenario_path``, ``seed`` for an emulated one)."""
        return json_column(self.session.get("metadata_json") or "{}", f"{self.path}: session metadata_json")

    def by_procedure(self) -> dict[str, list[dict]]:
        """The accepted steps grouped by their procedure, in the order recorded."""
        out: dict[str, list[dict]] = {}
        for st in self.steps:
            out.setdefault(st["procedure"], []).append(st)
        return out


def _rows(conn, sql, args=()):
    cur = conn.execute(sql, args)
    cols = [d[0] for d in cur.description]
    return [dict(zip(cols, r)) for r in cur.fetchall()]


def load_session(path: str, procedures: tuple[str, ...] | None = None, skip: tuple[str, ...] = ()) -> SessionData:
    """Every accepted step (of ``procedures`` only, when given; none of ``skip``) with the readings of its accepted
    (last) attempt; opened read-only."""
    conn = connect_readonly(path)
    try:
        return _load(conn, path, procedures, skip)
    except sqlite3.DatabaseError as exc:
        raise StoreError(f"{path}: damaged database ({exc})") from None
    finally:
        conn.close()


class SessionReader:
    """:func:`load_session` for a session read again and again while it is recorded (:mod:`offline.reduction.live`):
    one read-only connection, opened and checked on the first read and kept; the session row, plan, set-up and
    devices read on the first read and on every whole read (``procedures`` None), the plan and set-up parsed again
    only when their text changed.  A read of some procedures gives their steps with the first read's session row,
    plan, set-up and devices (a recording session changes only its row's exit status, which the whole read at its end
    gives).

    Why: :func:`load_session` opens the file and checks it (``PRAGMA quick_check`` reads every page) and parses the
    set-up every time: about 8 ms a read, three of them between the compliance procedure's last step and the pose
    set's model."""

    def __init__(self):
        self.conn: sqlite3.Connection | None = None
        self.header: SessionData | None = None       # the last whole (or first) read, its steps aside

    def __call__(self, path: str, procedures: tuple[str, ...] | None = None, skip: tuple[str, ...] = ()) -> SessionData:
        if self.conn is None:
            self.conn = connect_readonly(path)
        try:
            if self.header is not None and procedures is not None:
                return replace(self.header, steps=_steps(self.conn, path, self.header.session["session_id"],
                                                         procedures, skip))
            data = _load(self.conn, path, procedures, skip, self.header)
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{path}: damaged database ({exc})") from None
        self.header = replace(data, steps=[])
        return data

    def close(self) -> None:
        if self.conn is not None:
            self.conn.close()
            self.conn = None


def _load(conn, path: str, procedures: tuple[str, ...] | None = None, skip: tuple[str, ...] = (),
          before: SessionData | None = None) -> SessionData:
    """The rows of :func:`load_session`, each JSON column and array blob checked as it is read; ``before``: an
    earlier read whose plan and set-up serve when their text is the same."""
    sess = _rows(conn, "SELECT * FROM session ORDER BY session_id LIMIT 1")
    if not sess:
        raise RobocalError(f"{path}: holds no session")
    s = sess[0]
    steps = _steps(conn, path, s["session_id"], procedures, skip)
    devices = _rows(conn, "SELECT role, driver, url, identity_json FROM device")
    same = before is not None and (before.session["plan_json"], before.session["setup_json"]) == \
        (s["plan_json"], s["setup_json"])
    return SessionData(path, s, before.plan if same else json_column(s["plan_json"], f"{path}: session plan_json"),
                       before.setup if same else
                       BenchSetup.of(setup_from_text(s["setup_json"], f"{path}: session setup_json")), steps, devices)


def _steps(conn, path: str, session_id: int, procedures: tuple[str, ...] | None, skip: tuple[str, ...]) -> list[dict]:
    """The accepted steps of :func:`load_session` (of ``procedures`` only, when given; none of ``skip``)."""
    steps = _rows(conn, f"SELECT * FROM step WHERE session_id=? AND status='accepted'{_only('', procedures, skip)} "
                        f"ORDER BY seq", (session_id, *(procedures or ()), *skip))
    scope = (session_id, procedures, skip)
    readings = _by_step(conn, "reading", "station, target, face, repeat, hz_rad, v_rad", "reading_id", *scope)
    inputs = _by_step(conn, "operator_input", "name, value", "input_id", *scope)
    chunks = _by_step(conn, "encoder_chunk", "counts", "chunk_id", *scope)
    for st in steps:
        i = st["step_id"]
        st["spec"] = json_column(st["spec_json"], f"{path}: step {st['key']!r}: spec_json")
        st["readings"] = readings.get(i, [])
        st["inputs"] = {r["name"]: r["value"] for r in inputs.get(i, [])}
        st["counts"] = _counts(chunks.get(i, []), f"{path}: step {st['key']!r}: encoder counts")
    return steps


def _by_step(conn, table: str, columns: str, order: str, session_id: int, procedures: tuple[str, ...] | None,
             skip: tuple[str, ...]) -> dict[int, list[dict]]:
    """The rows of ``table`` recorded in the accepted (last) attempt of each accepted step (of ``procedures`` only,
    when given; none of ``skip``), ``columns`` only, grouped by step in ``order``: one query per table, not one per
    step (a demo session's 285 steps took 855 queries, a third of the load)."""
    cur = conn.execute(f"SELECT t.step_id, {columns} FROM {table} t JOIN step s ON s.step_id = t.step_id "
                       f"AND t.attempt = s.attempts WHERE s.session_id=? AND s.status='accepted'"
                       f"{_only('s.', procedures, skip)} "
                       f"ORDER BY t.{order}", (session_id, *(procedures or ()), *skip))
    cols = [d[0] for d in cur.description][1:]
    out: dict[int, list[dict]] = {}
    for step_id, *values in cur.fetchall():
        out.setdefault(step_id, []).append(dict(zip(cols, values)))
    return out


def _only(table: str, procedures: tuple[str, ...] | None, skip: tuple[str, ...]) -> str:
    """The SQL condition on ``{table}procedure`` for :func:`load_session`'s ``procedures`` and ``skip`` (parameters
    in that order)."""
    only = "" if procedures is None else f" AND {table}procedure IN ({', '.join('?' * len(procedures))})"
    if skip:
        only += f" AND {table}procedure NOT IN ({', '.join('?' * len(skip))})"
    return only


def _counts(chunks: list[dict], where: str) -> np.ndarray | None:
    """The encoder counts of a step's chunks, one (samples, joints) array; damaged blobs are one line."""
    if not chunks:
        return None
    arrays = [from_npy(c["counts"], where) for c in chunks]
    if any(a.ndim != 2 or a.shape[1] != arrays[0].shape[1] for a in arrays):
        raise StoreError(f"{where}: damaged array data (chunks of different shapes)")
    return np.concatenate(arrays)
