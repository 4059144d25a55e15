"""Session database: schema, migrations, refusal of foreign/corrupt/newer files, read-only reprocessing."""
from __future__ import annotations

import sqlite3

import numpy as np
import pytest

from acq.session import store as st


def _new(tmp_path, name="s.db"):
    return st.SessionStore.create(tmp_path / name, "t", {"procedures": []}, {"x": 1})


def test_create_sets_schema_and_wal(tmp_path):
    s = _new(tmp_path)
    c = s.conn
    assert c.execute("PRAGMA user_version").fetchone()[0] == st.SCHEMA_VERSION
    assert c.execute("PRAGMA application_id").fetchone()[0] == st.APPLICATION_ID
    assert c.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    s.close()


def test_step_is_atomic_and_raw_kept(tmp_path):
    s = _new(tmp_path)
    did = s.add_device("theodolite A", "geocom", "x", {})
    r = {"attempt": 1, "device_id": did, "station": "A", "target": "P", "face": 1, "repeat": 0, "hz_rad": 1.0,
         "v_rad": 1.5, "t_wall_s": 0.0, "t_mono_s": 0.0, "command": "c", "raw": b"%R1P,0,1:0,1,2"}
    s.write_step(st.StepRecord("a", "poses", "t", "i", "accepted", 1, 0, 0, {}, readings=[r]))
    bad = dict(r, device_id=999)                        # foreign key violation -> whole step rolled back
    with pytest.raises(sqlite3.IntegrityError):
        s.write_step(st.StepRecord("b", "poses", "t", "i", "accepted", 1, 0, 0, {}, readings=[r, bad]))
    assert s.done_keys() == {"a"}
    assert s.conn.execute("SELECT count(*), max(raw) FROM reading").fetchone() == (1, b"%R1P,0,1:0,1,2")
    s.close()


def test_migration_from_v1(tmp_path):
    p = tmp_path / "old.db"
    c = sqlite3.connect(p, isolation_level=None)
    st.migrate(c, 1)
    assert c.execute("PRAGMA user_version").fetchone()[0] == 1
    c.close()
    with pytest.raises(st.StoreError, match="older"):
        st.connect_readonly(p)
    c = st.connect(p)                                   # read-write open upgrades
    assert c.execute("PRAGMA user_version").fetchone()[0] == 2
    assert c.execute("SELECT count(*) FROM sqlite_master WHERE name='event_log'").fetchone()[0] == 1
    c.close()


def test_newer_schema_refused(tmp_path):
    s = _new(tmp_path)
    s.conn.execute(f"PRAGMA user_version = {st.SCHEMA_VERSION + 1}")
    s.close()
    for opener in (st.connect, st.connect_readonly, st.SessionStore.open):
        with pytest.raises(st.StoreError, match="newer robocal"):
            opener(tmp_path / "s.db")


def test_foreign_and_corrupt_files_refused(tmp_path):
    f = tmp_path / "foreign.db"
    c = sqlite3.connect(f)
    c.execute("CREATE TABLE x (a)")
    c.commit()
    c.close()
    with pytest.raises(st.StoreError, match="another application"):
        st.SessionStore.open(f)
    g = tmp_path / "garbage.db"
    g.write_bytes(b"this is not sqlite" * 100)
    with pytest.raises(st.StoreError, match="not a robocal session database"):
        st.connect_readonly(g)
    with pytest.raises(st.StoreError, match="not a robocal session database"):
        st.SessionStore.open(g)
    with pytest.raises(st.StoreError, match="no such"):
        st.SessionStore.open(tmp_path / "missing.db")


def test_readonly_cannot_write(tmp_path):
    _new(tmp_path).close()
    c = st.connect_readonly(tmp_path / "s.db")
    with pytest.raises(sqlite3.OperationalError):
        c.execute("DELETE FROM step")
    c.close()


def test_create_refuses_existing(tmp_path):
    _new(tmp_path).close()
    with pytest.raises(st.StoreError, match="exists already"):
        _new(tmp_path)


def test_arrays_are_stored_as_np_save_writes_them():
    """to_npy keeps np.save's header per dtype and shape: the stored bytes must stay exactly np.save's (other tools
    read the blobs with np.load), for C-ordered arrays and everything that goes through np.save itself."""
    import io
    from acq.session.store import from_npy, to_npy
    rng = np.random.default_rng(0)
    cases = [np.arange(10, dtype=np.int64), rng.random(7), rng.random((3, 6)), np.zeros(0), np.zeros((0, 6), np.int64),
             np.array(3.5), rng.random((4, 3)).T, np.arange(12, dtype=np.int32).reshape(3, 4)[:, ::2], [1, 2, 3],
             np.array([True, False]), rng.random((2, 3)).astype(">f8")]
    for a in cases + cases:                                     # twice: the kept header serves the second time
        buf = io.BytesIO()
        np.save(buf, np.asarray(a), allow_pickle=False)
        assert to_npy(a) == buf.getvalue(), a
        if np.asarray(a).dtype.kind in "iuf":                   # what the store keeps (it refuses the rest)
            np.testing.assert_array_equal(from_npy(to_npy(a)), np.asarray(a))
            # read back as np.load reads it (its header parsed once per distinct header): dtype, shape, order, a
            # writable copy
            got, ref = from_npy(buf.getvalue()), np.load(io.BytesIO(buf.getvalue()))
            assert (got.dtype, got.shape, got.flags.f_contiguous, got.flags.writeable) == \
                (ref.dtype, ref.shape, ref.flags.f_contiguous, True), a
            np.testing.assert_array_equal(got, ref)


def test_damaged_arrays_are_named_as_np_load_finds_them():
    """A blob cut short or with a damaged header is one line naming where it is, as np.load's checks find it."""
    from acq.session.store import StoreError, from_npy, to_npy
    good = to_npy(np.arange(6.0))
    for bad in (good[:-3], b"\x93NUMPY\x01\x00garbage", b"junk", b""):
        with pytest.raises(StoreError, match="^cap 3: damaged array data"):
            from_npy(bad, "cap 3")
