"""Fuzz targets for the file readers (issue 17 item 7): robot and scenario TOML, model and set-up JSON, pose and
readings CSV, session database.

Same shape as ``tests/fakes/fuzz_targets.py`` (whose :class:`Target`, byte mutations and :func:`outcome` this
reuses): a target takes the bytes of a file, writes them to disk and runs the reader as a command would.  A clean
rejection is a :class:`RobocalError` (the one line the user sees); anything else is a crash.  Besides byte
mutations, the JSON targets get value-level damage (a number becomes NaN, 1e308, a string, a deep list ...) and the
session database gets SQL-level damage (a column of a row set to garbage): that is where the readers used to crash.
"""
from __future__ import annotations

import functools
import json
import random
import shutil
import sqlite3
import tempfile
from importlib import resources
from pathlib import Path

import numpy as np

from calib.errors import RobocalError
from tests.fakes.fuzz_targets import Target, generate

_DIR = Path(tempfile.mkdtemp(prefix="robocal-fuzz-files-"))
Q_DEG = np.array([[10.0, -40.0, 70.0, 30.0, -20.0, 50.0]])


def _file(name: str, data: bytes) -> Path:
    p = _DIR / name
    p.write_bytes(data)
    return p


def _robot(data: bytes) -> None:
    from calib.loading import load_robot
    load_robot(_file("robot.toml", data))


def _scenario(data: bytes) -> None:
    from sim.twin import load_scenario
    load_scenario(_file("scenario.toml", data))


def _model(data: bytes) -> None:
    """What ``robocal compensate`` does with a model file: load it, correct a command, predict the point."""
    from calib.compensate import compensate_command, load_model, nominal_in_same_frame, predict
    im = load_model(_file("model.json", data))
    q = np.radians(Q_DEG[:, :im.model.robot.n])
    compensate_command(im, nominal_in_same_frame(im), q)
    predict(im, q)


def _setup(data: bytes) -> None:
    from acq.session.setup_file import read_setup
    read_setup(_file("setup.json", data))


def _pose_csv(data: bytes) -> None:
    from calib.posecsv import read_pose_csv
    read_pose_csv(_file("poses.csv", data))


def _readings_csv(data: bytes) -> None:
    from offline.exchange import _reading_steps
    _reading_steps(str(_file("readings.csv", data)))


def _session_db(data: bytes) -> None:
    from app.reprocess import load_session
    path = _file("session.db", data)
    for extra in ("-wal", "-shm"):
        Path(f"{path}{extra}").unlink(missing_ok=True)
    load_session(str(path))


# -- seeds -------------------------------------------------------------------------------------------------------
def _data(name: str) -> bytes:
    return (resources.files("calib") / "data" / name).read_bytes()


@functools.lru_cache(maxsize=None)
def _twin_files() -> dict[str, bytes]:
    """A pose CSV from the twin, the model identified from it and a session imported from it (made once)."""
    from app.cli import main
    d = Path(tempfile.mkdtemp(prefix="robocal-fuzz-seeds-"))
    import contextlib
    import io
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["twin", "--poses", "30", "--export", str(d / "p.csv")]) == 0
        assert main(["identify", str(d / "p.csv"), "--effect", "transmission_error:4:0.9", "--effect",
                     "joint_compliance:3", "--out", str(d / "m.json")]) == 0
        assert main(["import", str(d / "p.csv"), "--db", str(d / "s.db")]) == 0
    out = {k: (d / f).read_bytes() for k, f in (("poses", "p.csv"), ("model", "m.json"), ("db", "s.db"))}
    shutil.rmtree(d, ignore_errors=True)
    return out


def _setup_seed() -> bytes:
    from app.commands.session import setup_template
    return json.dumps(setup_template(), indent=1).encode()


READINGS = (b"step,procedure,station,target,face,hz_deg,v_deg,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n"
            b"ruler/p1/C,ruler,A,C,1,12.5,91.25,,,,,,\nruler/p1/C,ruler,B,C,1,350.5,90.75,,,,,,\n"
            b"sweep/j2/03,sweep,A,P,2,192.5,268.75,0,-90,90,0,0,0\n")


@functools.lru_cache(maxsize=None)
def targets() -> dict[str, Target]:
    """The file targets (seeds made on first use: the model seed needs an identification)."""
    tw = _twin_files()
    table = [
        Target("robot TOML", _robot, (RobocalError,), (_data("puma560.toml"), _data("tiago_arm.toml"))),
        Target("scenario TOML", _scenario, (RobocalError,), (_data("twin_default.toml"),)),
        Target("model JSON", _model, (RobocalError,), (tw["model"],)),
        Target("set-up JSON", _setup, (RobocalError,), (_setup_seed(),)),
        Target("pose CSV", _pose_csv, (RobocalError,), (tw["poses"],)),
        Target("readings CSV", _readings_csv, (RobocalError,), (READINGS,)),
        Target("session database", _session_db, (RobocalError,), (tw["db"],)),
    ]
    return {t.name: t for t in table}


# -- structured damage -------------------------------------------------------------------------------------------
BAD_VALUES = (float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 1e-308, 0, -1, 10 ** 40, "12", "", None,
              True, [], {}, [[[[]]]], [1.0, 2.0], {"type": "backlash", "joint": 99}, "x" * 1000)


def _nodes(doc, path=()):
    yield path
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _nodes(v, path + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _nodes(v, path + (i,))


def damage_json(rng: random.Random, seed: bytes) -> bytes:
    """One to three values of a JSON document replaced by damaged ones, or removed."""
    doc = json.loads(seed)
    for _ in range(rng.randint(1, 3)):
        paths = [p for p in _nodes(doc) if p]
        path = rng.choice(paths)
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        if rng.random() < 0.15 and isinstance(parent, dict):
            del parent[path[-1]]
        elif rng.random() < 0.5 and isinstance(parent[path[-1]], (int, float)) and not isinstance(parent[path[-1]],
                                                                                                   bool):
            parent[path[-1]] = parent[path[-1]] * rng.choice((-1, 1e3, 1e-3, 1e30, 0))
        else:
            parent[path[-1]] = rng.choice(BAD_VALUES)
    return json.dumps(doc).encode()


SQL_DAMAGE = (
    ("session", ("setup_json", "plan_json", "metadata_json")), ("step", ("spec_json", "attempts", "status", "key")),
    ("operator_input", ("value", "name", "attempt")), ("reading", ("hz_rad", "v_rad", "station")),
    ("encoder_chunk", ("counts",)),
)
SQL_VALUES = (None, "", "{", "[1, 2", "nan", '{"stations": 1}', b"\x93NUMPY\xff\xff", b"", 10 ** 18, -1, 1e308,
              '{"pose_deg": "x"}', '{"pose_deg": [1e308, 0, 0, 0, 0, 0]}', "[]")


def damage_db(rng: random.Random, seed: bytes) -> bytes:
    """A copy of the session database with one to three cells set to garbage (or a row deleted)."""
    path = _DIR / "damage.db"
    path.write_bytes(seed)
    con = sqlite3.connect(path)
    try:
        for _ in range(rng.randint(1, 3)):
            table, cols = rng.choice(SQL_DAMAGE)
            if rng.random() < 0.1:
                con.execute(f"DELETE FROM {table} WHERE rowid = (SELECT min(rowid) FROM {table})")
                continue
            con.execute(f"UPDATE {table} SET {rng.choice(cols)} = ? WHERE rowid IN "
                        f"(SELECT rowid FROM {table} ORDER BY random() LIMIT 1)", (rng.choice(SQL_VALUES),))
        con.commit()
    except sqlite3.IntegrityError:
        pass                                      # a NOT NULL or CHECK constraint: the file stays as it was
    finally:
        con.close()
    return path.read_bytes()


def generate_file(rng: random.Random, target: Target) -> bytes:
    """An input for a file target: structured damage for JSON and the database, else byte mutations."""
    if target.name in ("model JSON", "set-up JSON") and rng.random() < 0.6:
        return damage_json(rng, rng.choice(target.seeds))
    if target.name == "session database" and rng.random() < 0.8:
        return damage_db(rng, rng.choice(target.seeds))
    return generate(rng, target)
