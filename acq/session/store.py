"""The session database: one SQLite file per session, fixed versioned schema, WAL, committed at every step.

Why this shape (see /work/shared/reference/acquisition-style.md §7.5): long, narrow, fixed tables (no table per
session, no dynamic columns); ``PRAGMA user_version`` is the schema version and ``MIGRATIONS[v]`` upgrades v-1 -> v
atomically; ``PRAGMA application_id`` marks the file as robocal's, so a foreign SQLite file is refused instead of
being "migrated".  A file newer than this code is refused (its meaning is unknown to us).

Durability: ``synchronous=FULL`` + WAL (OFF for an emulated session on a simulated clock, which can be recorded
again: see :func:`connect`).  The runner writes a whole step (its row, every raw reading of every attempt,
the encoder stream chunks, operator inputs and check results) in **one transaction** when the operator decides
(accept or skip), so a crash loses at most the step in progress and never leaves half a step.  Raw rows are
insert-only: calibration results go to ``result`` with provenance and never update raw tables.

Units: every column that carries a physical quantity names its unit (``hz_rad``, ``t_wall_s``, ``value`` with a
``unit`` column beside it for operator inputs).
"""
from __future__ import annotations

import io
import json
import os
import sqlite3
import time
import uuid
from contextlib import contextmanager
from functools import lru_cache
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from calib.errors import RobocalError
from calib.jsonfile import parse_json
from calib.provenance import robocal_version

APPLICATION_ID = 0x52424331          # "RBC1"
SCHEMA_VERSION = 2

_V1 = """
CREATE TABLE session (
  session_id      INTEGER PRIMARY KEY,
  guid            TEXT NOT NULL UNIQUE,
  title           TEXT NOT NULL,
  operator        TEXT NOT NULL DEFAULT '',
  app_version     TEXT NOT NULL,
  created_unix_s  REAL NOT NULL,
  ended_unix_s    REAL,
  exit_status     TEXT CHECK (exit_status IN ('success', 'abort', 'fail', 'paused')),
  error           TEXT,
  plan_json       TEXT NOT NULL,        -- procedures and their parameters (what the steps were generated from)
  setup_json      TEXT NOT NULL,        -- setup geometry: robot description, ruler, tool targets, gauges
  metadata_json   TEXT NOT NULL DEFAULT '{}'
);
CREATE TABLE device (
  device_id       INTEGER PRIMARY KEY,
  session_id      INTEGER NOT NULL REFERENCES session,
  role            TEXT NOT NULL,        -- theodolite A, theodolite B, encoder tap
  driver          TEXT NOT NULL,
  url             TEXT NOT NULL,
  identity_json   TEXT NOT NULL,
  settings_json   TEXT NOT NULL DEFAULT '{}',
  opened_unix_s   REAL NOT NULL
);
CREATE TABLE step (
  step_id         INTEGER PRIMARY KEY,
  session_id      INTEGER NOT NULL REFERENCES session,
  seq             INTEGER NOT NULL,
  key             TEXT NOT NULL,        -- stable across resumes: procedure/joint/index
  procedure       TEXT NOT NULL,
  title           TEXT NOT NULL,
  instruction     TEXT NOT NULL,
  status          TEXT NOT NULL CHECK (status IN ('accepted', 'skipped')),
  attempts        INTEGER NOT NULL,     -- attempts made (the accepted one is the last)
  started_unix_s  REAL NOT NULL,
  ended_unix_s    REAL NOT NULL,
  spec_json       TEXT NOT NULL,        -- the step as generated: pose (deg), targets, loads, gauges
  note            TEXT NOT NULL DEFAULT '',
  UNIQUE (session_id, key), UNIQUE (session_id, seq)
);
CREATE TABLE reading (
  reading_id      INTEGER PRIMARY KEY,
  step_id         INTEGER NOT NULL REFERENCES step,
  attempt         INTEGER NOT NULL,
  device_id       INTEGER NOT NULL REFERENCES device,
  station         TEXT NOT NULL,
  target          TEXT NOT NULL,
  face            INTEGER NOT NULL,
  repeat          INTEGER NOT NULL,
  hz_rad          REAL NOT NULL,
  v_rad           REAL NOT NULL,
  t_wall_s        REAL NOT NULL,
  t_mono_s        REAL NOT NULL,
  command         TEXT NOT NULL,
  warnings        TEXT NOT NULL DEFAULT '',
  raw             BLOB NOT NULL         -- the exact reply frame
);
CREATE INDEX reading_by_step ON reading(step_id, attempt);
CREATE TABLE encoder_chunk (
  chunk_id        INTEGER PRIMARY KEY,
  step_id         INTEGER NOT NULL REFERENCES step,
  attempt         INTEGER NOT NULL,
  device_id       INTEGER NOT NULL REFERENCES device,
  phase           TEXT NOT NULL DEFAULT 'settle',
  n_samples       INTEGER NOT NULL,
  t0_mono_s       REAL NOT NULL,
  seq             BLOB NOT NULL,        -- npy int64 (n,)
  t_device_us     BLOB NOT NULL,        -- npy int64 (n,)
  t_mono_s        BLOB NOT NULL,        -- npy float64 (n,)
  counts_wire     BLOB NOT NULL,        -- npy int64 (n, joints): exactly as received
  counts          BLOB NOT NULL         -- npy int64 (n, joints): unwrapped
);
CREATE INDEX chunk_by_step ON encoder_chunk(step_id, attempt);
CREATE TABLE operator_input (
  input_id        INTEGER PRIMARY KEY,
  step_id         INTEGER NOT NULL REFERENCES step,
  attempt         INTEGER NOT NULL,
  name            TEXT NOT NULL,
  value           REAL,
  unit            TEXT NOT NULL DEFAULT '',
  text            TEXT NOT NULL DEFAULT '',
  t_wall_s        REAL NOT NULL
);
CREATE TABLE check_result (
  check_id        INTEGER PRIMARY KEY,
  step_id         INTEGER NOT NULL REFERENCES step,
  attempt         INTEGER NOT NULL,
  name            TEXT NOT NULL,
  passed          INTEGER NOT NULL,
  value           REAL,
  limit_value     REAL,
  unit            TEXT NOT NULL DEFAULT '',
  message         TEXT NOT NULL
);
CREATE TABLE result (
  result_id       INTEGER PRIMARY KEY,
  guid            TEXT NOT NULL UNIQUE,
  session_guid    TEXT NOT NULL,
  created_unix_s  REAL NOT NULL,
  code_version    TEXT NOT NULL,
  algorithm       TEXT NOT NULL,
  params_json     TEXT NOT NULL,
  result_json     TEXT NOT NULL
);
"""

_V2 = """
CREATE TABLE event_log (
  event_id        INTEGER PRIMARY KEY,
  session_id      INTEGER NOT NULL REFERENCES session,
  t_wall_s        REAL NOT NULL,
  kind            TEXT NOT NULL,        -- started, resumed, paused, finished, aborted
  detail          TEXT NOT NULL DEFAULT ''
);
CREATE INDEX step_by_procedure ON step(session_id, procedure);
"""


def _script(sql: str) -> Callable[[sqlite3.Connection], None]:
    def up(conn: sqlite3.Connection) -> None:
        buf = ""
        for line in sql.splitlines(keepends=True):
            buf += line
            if sqlite3.complete_statement(buf):
                conn.execute(buf)
                buf = ""
        if buf.strip():
            raise StoreError(f"migration script ends with an incomplete statement: {buf[:60]!r}")
    return up


#: version -> upgrade from version - 1 (run inside one transaction each)
MIGRATIONS: dict[int, Callable[[sqlite3.Connection], None]] = {1: _script(_V1), 2: _script(_V2)}


class StoreError(RobocalError):
    """The file is not a robocal session database this code can open."""


def code_version() -> str:
    """The robocal version stored with sessions and results (one definition: :mod:`calib.provenance`)."""
    return robocal_version()


# -- npy blobs ---------------------------------------------------------------------------------------------------
def to_npy(a: np.ndarray) -> bytes:
    """The bytes ``np.save`` writes for ``a``.  A C-ordered array of a plain dtype: its header, kept per dtype and
    shape (a session stores five arrays per encoder window, and np.save formatted the same header each time), then
    its data; anything else through ``np.save`` itself."""
    a = np.asarray(a)
    if a.flags.c_contiguous and a.dtype.fields is None and not a.dtype.hasobject:
        return _npy_header(a.dtype.str, a.shape) + a.tobytes()
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()


@lru_cache(maxsize=64)
def _npy_header(dtype: str, shape: tuple) -> bytes:
    """np.save's header for a C-ordered array of ``dtype`` (its ``str``) and ``shape``: np.save's own output for such
    an array, less its data."""
    probe = np.zeros(shape, np.dtype(dtype))
    buf = io.BytesIO()
    np.save(buf, probe, allow_pickle=False)
    return buf.getvalue()[: len(buf.getvalue()) - probe.nbytes]


def from_npy(b: bytes, where: str = "array blob") -> np.ndarray:
    """An array stored by :func:`to_npy`; a damaged blob is one line naming ``where`` (file, table, row).

    A version 1.0 header of a C-ordered numeric array is parsed once per distinct header (a session's encoder windows
    share a few: np.load parsed each one's text with ``ast.literal_eval``) and the data copied out after it; any other
    blob, and one whose data is not the header's size, goes through ``np.load`` -- and its errors."""
    fast = _from_npy_v1(b)
    if fast is not None:
        return fast
    try:
        a = np.load(io.BytesIO(b), allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 -- numpy raises ValueError, EOFError, OSError, TypeError ... on garbage
        raise StoreError(f"{where}: damaged array data ({type(exc).__name__}: {' '.join(str(exc).split())[:80]})") \
            from None
    if not isinstance(a, np.ndarray) or a.dtype.kind not in "iuf":
        raise StoreError(f"{where}: damaged array data (not a numeric array)")
    return a


def _from_npy_v1(b: bytes) -> np.ndarray | None:
    if len(b) < 10 or b[:8] != b"\x93NUMPY\x01\x00":
        return None
    end = 10 + int.from_bytes(b[8:10], "little")
    meta = _npy_v1_header(bytes(b[:end]))
    if meta is None:
        return None
    dtype, shape, nbytes = meta
    if len(b) - end != nbytes:
        return None
    return np.frombuffer(b, dtype, offset=end).reshape(shape).copy()


@lru_cache(maxsize=64)
def _npy_v1_header(head: bytes) -> tuple | None:
    """(dtype, shape, data bytes) of a version 1.0 npy header of a C-ordered numeric array, else None."""
    try:
        buf = io.BytesIO(head)
        np.lib.format.read_magic(buf)
        shape, fortran, dtype = np.lib.format.read_array_header_1_0(buf)
    except Exception:  # noqa: BLE001 -- a damaged header: np.load says what is wrong
        return None
    if fortran or dtype.kind not in "iuf" or dtype.fields is not None:
        return None
    return dtype, shape, int(np.prod(shape, dtype=np.int64)) * dtype.itemsize


def json_column(text, where: str):
    """A JSON object column (plan, set-up, metadata, step spec); damaged JSON is one line naming ``where``."""
    if not isinstance(text, str):
        raise StoreError(f"{where}: damaged: not JSON text")
    doc = parse_json(text, where)
    if not isinstance(doc, dict):
        raise StoreError(f"{where}: damaged: not a JSON object")
    return doc


# -- opening -----------------------------------------------------------------------------------------------------
def _probe(conn: sqlite3.Connection, path: str) -> tuple[int, int]:
    try:
        app = conn.execute("PRAGMA application_id").fetchone()[0]
        ver = conn.execute("PRAGMA user_version").fetchone()[0]
        tables = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
    except sqlite3.DatabaseError as exc:
        raise StoreError(f"{path}: not a robocal session database ({exc})") from None
    if app != APPLICATION_ID and (tables or ver):
        raise StoreError(f"{path}: not a robocal session database (SQLite file of another application)")
    if app != APPLICATION_ID and os.path.exists(path) and os.path.getsize(path) == 0:
        app = -1  # an empty file: not ours (the caller decides whether it may create a session in it)
    if ver > SCHEMA_VERSION:
        raise StoreError(f"{path}: made by a newer robocal (schema version {ver}; this one reads up to "
                         f"{SCHEMA_VERSION}); upgrade robocal to open it")
    return app, ver


def migrate(conn: sqlite3.Connection, target: int = SCHEMA_VERSION) -> int:
    """Upgrade the schema to ``target`` one version at a time, each in its own transaction; returns the version."""
    ver = conn.execute("PRAGMA user_version").fetchone()[0]
    while ver < target:
        nxt = ver + 1
        conn.execute("BEGIN IMMEDIATE")
        try:
            MIGRATIONS[nxt](conn)
            conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            conn.execute(f"PRAGMA user_version = {nxt}")
            conn.execute("COMMIT")
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        ver = nxt
    return ver


def connect(path: str | Path, *, create: bool = False, target_version: int = SCHEMA_VERSION,
            durable: bool = True) -> sqlite3.Connection:
    """A read-write connection (WAL, foreign keys, synchronous FULL), migrated to ``target_version``.

    ``durable=False`` (synchronous OFF) is for sessions that can be recorded again -- an emulated session on a
    simulated clock: a crash of the program still loses no committed step (each commit is in the operating system's
    hands), only a power cut may lose or damage the file -- and nothing waits for the disk: NORMAL flushed the WAL at
    every automatic checkpoint, 10-45 ms each on a quiet disk (about 0.1 s of the demo's recording); on the shared
    2-core machine under load 4 (2026-11-26 14:18 UTC) the recording waited on the disk 26-50 times (voluntary context
    switches), 11.4-12.3 s wall, against none and 9.8-10.5 s with OFF, the code otherwise the same."""
    p = str(path)
    if not create and not os.path.exists(p):
        raise StoreError(f"{p}: no such session database")
    conn = sqlite3.connect(p, isolation_level=None, timeout=10.0, check_same_thread=False)
    try:
        app, _ = _probe(conn, p)
        if app != APPLICATION_ID and not create:
            # never write robocal's schema into a file that is not a robocal database (an empty or foreign file)
            raise StoreError(f"{p}: not a robocal session database (an empty file or an empty SQLite database)")
        conn.execute("PRAGMA journal_mode=WAL")
        conn.execute(f"PRAGMA synchronous={'FULL' if durable else 'OFF'}")
        conn.execute("PRAGMA foreign_keys=ON")
        conn.execute("PRAGMA busy_timeout=10000")
        migrate(conn, target_version)
        ok = conn.execute("PRAGMA quick_check").fetchone()[0]
        if ok != "ok":
            raise StoreError(f"{p}: database is damaged ({ok})")
    except sqlite3.DatabaseError as exc:
        conn.close()
        raise StoreError(f"{p}: not a robocal session database ({exc})") from None
    except BaseException:
        conn.close()
        raise
    return conn


def _damaged_text_visible(raw: bytes) -> str:
    """Text columns of a damaged file: invalid UTF-8 shows as U+FFFD (a damaged JSON column then fails its parse
    with one line naming it) instead of an sqlite3 error in the middle of a read."""
    return raw.decode("utf-8", errors="replace")


def connect_readonly(path: str | Path) -> sqlite3.Connection:
    """Read-only connection (``mode=ro`` URI): reprocessing can never modify raw data."""
    p = str(path)
    if not os.path.exists(p):
        raise StoreError(f"{p}: no such session database")
    uri = Path(p).resolve().as_uri() + "?mode=ro"
    try:
        conn = sqlite3.connect(uri, uri=True, isolation_level=None, check_same_thread=False)
        conn.text_factory = _damaged_text_visible
        app, ver = _probe(conn, p)
        if app != APPLICATION_ID:
            conn.close()
            raise StoreError(f"{p}: not a robocal session database (an empty file or an empty SQLite database)")
        if ver < SCHEMA_VERSION:
            conn.close()
            raise StoreError(f"{p}: schema version {ver} is older than {SCHEMA_VERSION}; open it once with "
                             f"'robocal demo --resume --db {p}' or any read-write command to upgrade it")
        ok = conn.execute("PRAGMA quick_check").fetchone()[0]
    except sqlite3.DatabaseError as exc:
        raise StoreError(f"{p}: not a robocal session database ({exc})") from None
    if ok != "ok":
        conn.close()
        raise StoreError(f"{p}: database is damaged ({ok})")
    return conn


@contextmanager
def atomic(conn: sqlite3.Connection) -> Iterator[sqlite3.Connection]:
    """One write transaction (BEGIN IMMEDIATE so busy_timeout applies); rolled back on any exception."""
    conn.execute("BEGIN IMMEDIATE")
    try:
        yield conn
    except BaseException:
        conn.execute("ROLLBACK")
        raise
    conn.execute("COMMIT")


# -- the writer ------------------------------------------------------------------------------------------------
@dataclass
class StepRecord:
    """Everything one step produced, written in one transaction."""

    key: str
    procedure: str
    title: str
    instruction: str
    status: str                                  # accepted | skipped
    attempts: int
    started_unix_s: float
    ended_unix_s: float
    spec: dict
    note: str = ""
    readings: list[dict] | None = None           # keys: attempt, device_id, station, target, face, repeat, hz_rad...
    chunks: list[dict] | None = None             # keys: attempt, device_id, phase, arrays
    inputs: list[dict] | None = None             # keys: attempt, name, value, unit, text, t_wall_s
    checks: list[dict] | None = None             # keys: attempt, name, passed, value, limit_value, unit, message


class SessionStore:
    """Read-write access to one session database (the runner's single writer)."""

    def __init__(self, conn: sqlite3.Connection, path: str):
        self.conn = conn
        self.path = path
        row = conn.execute("SELECT session_id, guid FROM session ORDER BY session_id LIMIT 1").fetchone()
        self.session_id: int | None = row[0] if row else None
        self.guid: str | None = row[1] if row else None

    @classmethod
    def create(cls, path: str | Path, title: str, plan: dict, setup: dict, operator: str = "",
               metadata: dict | None = None, durable: bool = True) -> "SessionStore":
        """A new session in ``path``; ``durable``: see :func:`connect`."""
        p = str(path)
        conn = connect(p, create=True, durable=durable)
        st = cls(conn, p)
        if st.session_id is not None:           # (a file left by a crash during creation holds no session: reuse)
            conn.close()
            raise StoreError(f"{p}: exists already; use --resume to continue it or choose another --db")
        with atomic(conn):
            cur = conn.execute(
                "INSERT INTO session (guid, title, operator, app_version, created_unix_s, plan_json, setup_json, "
                "metadata_json) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (str(uuid.uuid4()), title, operator, code_version(), time.time(), json.dumps(plan),
                 json.dumps(setup), json.dumps(metadata or {})))
            st.session_id = cur.lastrowid
            conn.execute("INSERT INTO event_log (session_id, t_wall_s, kind) VALUES (?, ?, 'started')",
                         (st.session_id, time.time()))
        st.guid = conn.execute("SELECT guid FROM session WHERE session_id=?", (st.session_id,)).fetchone()[0]
        return st

    @classmethod
    def open(cls, path: str | Path, durable: bool = True) -> "SessionStore":
        p = str(path)
        conn = connect(p, durable=durable)
        st = cls(conn, p)
        if st.session_id is None:
            conn.close()
            raise StoreError(f"{p}: holds no session")
        return st

    def close(self) -> None:
        self.conn.close()

    # -- reads used by the runner ----------------------------------------------------------------------------------
    def session_row(self) -> dict:
        cur = self.conn.execute("SELECT * FROM session WHERE session_id=?", (self.session_id,))
        return dict(zip([d[0] for d in cur.description], cur.fetchone()))

    def done_keys(self) -> set[str]:
        return {r[0] for r in self.conn.execute("SELECT key FROM step WHERE session_id=?", (self.session_id,))}

    def next_seq(self) -> int:
        return self.conn.execute("SELECT coalesce(max(seq), 0) + 1 FROM step WHERE session_id=?",
                                 (self.session_id,)).fetchone()[0]

    # -- writes ------------------------------------------------------------------------------------------------
    def log(self, kind: str, detail: str = "") -> None:
        with atomic(self.conn):
            self.conn.execute("INSERT INTO event_log (session_id, t_wall_s, kind, detail) VALUES (?, ?, ?, ?)",
                              (self.session_id, time.time(), kind, detail))

    def add_device(self, role: str, driver: str, url: str, identity: dict, settings: dict | None = None) -> int:
        with atomic(self.conn):
            cur = self.conn.execute(
                "INSERT INTO device (session_id, role, driver, url, identity_json, settings_json, opened_unix_s) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (self.session_id, role, driver, url, json.dumps(identity), json.dumps(settings or {}), time.time()))
            return cur.lastrowid

    def write_step(self, rec: StepRecord) -> int:
        """The step and everything it produced, atomically (the runner's commit point)."""
        c = self.conn
        with atomic(c):
            # the next seq (:meth:`next_seq`) found by the insert itself: one statement a step less
            cur = c.execute(
                "INSERT INTO step (session_id, seq, key, procedure, title, instruction, status, attempts, "
                "started_unix_s, ended_unix_s, spec_json, note) VALUES (?, (SELECT coalesce(max(seq), 0) + 1 FROM "
                "step WHERE session_id=?), ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (self.session_id, self.session_id, rec.key, rec.procedure, rec.title, rec.instruction, rec.status,
                 rec.attempts, rec.started_unix_s, rec.ended_unix_s, json.dumps(rec.spec), rec.note))
            sid = cur.lastrowid
            if rec.readings:
                c.executemany(
                    "INSERT INTO reading (step_id, attempt, device_id, station, target, face, repeat, hz_rad, v_rad,"
                    " t_wall_s, t_mono_s, command, warnings, raw) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    [(sid, r["attempt"], r["device_id"], r["station"], r["target"], r["face"], r["repeat"],
                      r["hz_rad"], r["v_rad"], r["t_wall_s"], r["t_mono_s"], r["command"], r.get("warnings", ""),
                      r["raw"]) for r in rec.readings])
            for ch in rec.chunks or ():
                self._chunk(sid, ch)
            if rec.inputs:
                c.executemany(
                    "INSERT INTO operator_input (step_id, attempt, name, value, unit, text, t_wall_s) "
                    "VALUES (?, ?, ?, ?, ?, ?, ?)",
                    [(sid, i["attempt"], i["name"], i.get("value"), i.get("unit", ""), i.get("text", ""),
                      i.get("t_wall_s", time.time())) for i in rec.inputs])
            if rec.checks:
                c.executemany(
                    "INSERT INTO check_result (step_id, attempt, name, passed, value, limit_value, unit, message) "
                    "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                    [(sid, k["attempt"], k["name"], int(bool(k["passed"])), k.get("value"), k.get("limit_value"),
                      k.get("unit", ""), k["message"]) for k in rec.checks])
        return sid

    def _chunk(self, step_id: int, ch: dict) -> None:
        n = int(len(ch["seq"]))
        self.conn.execute(
            "INSERT INTO encoder_chunk (step_id, attempt, device_id, phase, n_samples, t0_mono_s, seq, t_device_us, "
            "t_mono_s, counts_wire, counts) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (step_id, ch["attempt"], ch["device_id"], ch.get("phase", "settle"), n,
             float(ch["t_mono_s"][0]) if n else 0.0,
             to_npy(np.asarray(ch["seq"], np.int64)), to_npy(np.asarray(ch["t_device_us"], np.int64)),
             to_npy(np.asarray(ch["t_mono_s"], float)), to_npy(np.asarray(ch["counts_wire"], np.int64)),
             to_npy(np.asarray(ch["counts"], np.int64))))

    def finish(self, exit_status: str, error: str | None = None) -> None:
        with atomic(self.conn):
            self.conn.execute("UPDATE session SET exit_status=?, error=?, ended_unix_s=? WHERE session_id=?",
                              (exit_status, error, time.time(), self.session_id))
            self.conn.execute("INSERT INTO event_log (session_id, t_wall_s, kind, detail) VALUES (?, ?, ?, ?)",
                              (self.session_id, time.time(), exit_status, error or ""))

    def reopen(self) -> None:
        """Mark a paused or crashed session as running again (exit_status NULL)."""
        with atomic(self.conn):
            self.conn.execute("UPDATE session SET exit_status=NULL, error=NULL, ended_unix_s=NULL WHERE session_id=?",
                              (self.session_id,))
            self.conn.execute("INSERT INTO event_log (session_id, t_wall_s, kind) VALUES (?, ?, 'resumed')",
                              (self.session_id, time.time()))


def save_result(path: str | Path, session_guid: str, algorithm: str, params: dict, result: dict) -> str:
    """Append a calibration result with provenance (a separate write; raw tables are not touched)."""
    conn = connect(path)
    try:
        g = str(uuid.uuid4())
        with atomic(conn):
            conn.execute("INSERT INTO result (guid, session_guid, created_unix_s, code_version, algorithm, "
                         "params_json, result_json) VALUES (?, ?, ?, ?, ?, ?, ?)",
                         (g, session_guid, time.time(), code_version(), algorithm, json.dumps(params),
                          json.dumps(result)))
        return g
    finally:
        conn.close()
