"""The on-disk cache (acq.cache) gives back exactly what the computation gave, recomputes when the inputs or robocal's
source change, and is skipped when turned off; the demo's pose set from the cache is the one chosen afresh."""
from __future__ import annotations

import numpy as np
import pytest

import acq.cache as cache


@pytest.fixture
def calls(tmp_path, monkeypatch):
    monkeypatch.setenv("ROBOCAL_CACHE_DIR", str(tmp_path))
    made = []

    def compute():
        made.append(1)
        return np.random.default_rng(len(made)).random((4, 6))
    return made, compute


def test_a_hit_is_the_computed_array_bit_for_bit(calls):
    made, compute = calls
    first = cache.cached_array("t", b"inputs", compute)
    again = cache.cached_array("t", b"inputs", compute)
    assert len(made) == 1
    assert again.dtype == first.dtype and np.array_equal(again, first)


def test_other_inputs_or_other_source_are_a_miss(calls, monkeypatch):
    made, compute = calls
    cache.cached_array("t", b"a", compute)
    cache.cached_array("t", b"b", compute)
    assert len(made) == 2
    monkeypatch.setattr(cache, "code_fingerprint", lambda: "edited")
    cache.cached_array("t", b"a", compute)
    assert len(made) == 3


def test_off_computes_every_time(calls, monkeypatch):
    made, compute = calls
    monkeypatch.setenv("ROBOCAL_CACHE_DIR", "off")
    cache.cached_array("t", b"a", compute)
    cache.cached_array("t", b"a", compute)
    assert len(made) == 2


def test_an_unwritable_cache_still_gives_the_value(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("ROBOCAL_CACHE_DIR", str(blocker / "sub"))
    with pytest.warns(UserWarning, match=r"cache folder .*sub cannot be written .*ROBOCAL_CACHE_DIR=off") as said:
        assert np.array_equal(cache.cached_array("t", b"a", lambda: np.arange(3.0)), np.arange(3.0))
        assert np.array_equal(cache.cached_array("t", b"b", lambda: np.arange(4.0)), np.arange(4.0))
    assert len(said) == 1                       # said once per folder, not on every computation


def test_the_demo_pose_set_from_the_cache_is_the_one_chosen_afresh(tmp_path, monkeypatch):
    from app.demo import _choose_poses, demo_poses
    from acq.session.setup import session_setup
    from app.demo import demo_setup
    from acq.session.setup_types import setup_of
    from sim.twin import Twin
    monkeypatch.setenv("ROBOCAL_CACHE_DIR", str(tmp_path))
    twin = Twin(seed=0)
    setup = setup_of(session_setup(demo_setup(twin), twin.robot))
    fresh = _choose_poses(twin, 0, 12, True, setup)
    stored = demo_poses(twin, 0, 12, True, setup)
    kept = demo_poses(twin, 0, 12, True, setup)
    assert len(list(tmp_path.iterdir())) == 1
    assert np.array_equal(fresh, stored) and np.array_equal(stored, kept)


def test_a_damaged_entry_is_computed_again(calls, tmp_path):
    made, compute = calls
    first = cache.cached_array("t", b"a", compute)
    for f in tmp_path.iterdir():
        f.write_bytes(b"")
    again = cache.cached_array("t", b"a", compute)
    assert len(made) == 2 and again.shape == first.shape
    assert np.array_equal(cache.cached_array("t", b"a", compute), again) and len(made) == 2


def test_the_fingerprint_covers_the_code_the_demo_pose_choice_runs():
    """The pose choice lives in app/demo.py and runs the twin of sim/: an edit there must be a miss."""
    import app.demo as demo
    import sim.twin as twin
    covered = {p.split("/")[0] for p in cache._SOURCES}
    for mod in (demo, twin, cache):
        assert mod.__name__.split(".")[0] in covered, mod.__name__


@pytest.mark.parametrize("stored", [np.arange(3.0), np.zeros((2, 6)), np.full((4, 6), np.nan), np.zeros((4, 6), int)])
def test_a_stored_entry_of_the_wrong_shape_or_kind_is_computed_again(calls, tmp_path, stored):
    """A damaged or tampered entry (another shape, not finite, not floats) is never handed back: computed again."""
    made, compute = calls
    first = cache.cached_array("t", b"a", compute, shape=(4, 6))
    (entry,) = tmp_path.glob("t-*.npy")
    np.save(entry, stored)
    again = cache.cached_array("t", b"a", compute, shape=(4, 6))
    assert len(made) == 2 and again.shape == (4, 6) and np.all(np.isfinite(again))
    assert not np.array_equal(again, stored) and first.shape == again.shape


def _same(a, b) -> bool:
    """Equal with the same types all the way down (a tuple is not a list, 1 is not 1.0)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b or (a != a and b != b)


def test_the_demo_plan_from_the_cache_is_the_one_made_afresh(tmp_path, monkeypatch):
    """The demo's plan kept as JSON is, type for type, the plan session_plan makes (the runs narrowed to sight, the
    ISO 9283 cube) for the same robot, set-up, pose set and seed; other transmission-error joints are another entry."""
    import json
    from app.demo import demo_plan, demo_poses, demo_setup
    from acq.session.plans import DEMO, session_plan
    from acq.session.setup import session_setup
    from acq.session.setup_types import setup_of
    from sim.twin import Twin
    monkeypatch.setenv("ROBOCAL_CACHE_DIR", str(tmp_path))
    twin = Twin(seed=0)
    setup = setup_of(session_setup(demo_setup(twin), twin.robot))
    fresh = session_plan(twin.robot, setup, DEMO, None, np.round(demo_poses(twin, 1, 12, True, setup), 3), 1)
    stored = demo_plan(twin, 1, n_poses=12, setup=setup)
    kept = demo_plan(twin, 1, n_poses=12, setup=setup)
    assert _same(fresh, stored) and _same(stored, kept) and kept is not stored
    assert json.dumps(kept) == json.dumps(fresh)
    assert len(list(tmp_path.glob("demo-plan-*.json"))) == 1
    other = demo_plan(twin, 1, n_poses=12, setup=setup, te_joints=[6])
    assert other["transmission"]["joints"] == [6] and len(list(tmp_path.glob("demo-plan-*.json"))) == 2


def test_a_json_entry_that_is_not_an_object_is_computed_again(tmp_path, monkeypatch):
    monkeypatch.setenv("ROBOCAL_CACHE_DIR", str(tmp_path))
    made = []

    def compute():
        made.append(1)
        return {"n": len(made), "x": (1.5, -0.0)}
    assert cache.cached_json("j", b"a", compute) == {"n": 1, "x": [1.5, -0.0]}         # read back as stored
    (entry,) = tmp_path.glob("j-*.json")
    for damaged in (b"", b"[1, 2]", b"{\"n\": "):
        entry.write_bytes(damaged)
        assert cache.cached_json("j", b"a", compute)["n"] == len(made)
    assert len(made) == 4 and cache.cached_json("j", b"a", compute)["n"] == 4


@pytest.fixture
def tree(tmp_path, monkeypatch):
    """A source tree of its own for code_fingerprint, and the cache in another folder."""
    root, folder = tmp_path / "src", tmp_path / "cache"
    (root / "pkg" / "sub").mkdir(parents=True)
    (root / "pkg" / "a.py").write_text("A = 1\n")
    (root / "pkg" / "sub" / "b.py").write_text("B = 2\n")
    monkeypatch.setattr(cache, "_ROOT", root)
    monkeypatch.setattr(cache, "_SOURCES", ("pkg",))
    monkeypatch.setenv("ROBOCAL_CACHE_DIR", str(folder))

    def fingerprint(off: bool = False) -> str:
        cache.code_fingerprint.cache_clear()
        if off:
            monkeypatch.setenv("ROBOCAL_CACHE_DIR", "off")
        try:
            return cache.code_fingerprint()
        finally:
            monkeypatch.setenv("ROBOCAL_CACHE_DIR", str(folder))
            cache.code_fingerprint.cache_clear()
    return root, folder, fingerprint


def test_the_kept_fingerprint_is_the_one_read_from_the_sources(tree):
    root, folder, fingerprint = tree
    read = fingerprint(off=True)
    assert fingerprint() == read and len(list(folder.glob("code-fingerprint-*.txt"))) == 1
    assert fingerprint() == read                                      # kept
    (kept,) = folder.glob("code-fingerprint-*.txt")
    kept.write_text("damaged")
    assert fingerprint() == read and kept.read_text() == read          # read again, kept again


def test_an_edit_an_added_or_a_removed_file_is_another_fingerprint(tree):
    """An edit of the same size is another fingerprint (its time stamp moved); putting the old content back with its
    old time stamp gives the old one; a file added or removed is another."""
    import os
    root, folder, fingerprint = tree
    a = root / "pkg" / "a.py"
    first, st = fingerprint(), a.stat()
    a.write_text("A = 3\n")
    os.utime(a, ns=(st.st_atime_ns, st.st_mtime_ns + 1000))
    edited = fingerprint()
    assert edited != first and edited == fingerprint(off=True)
    a.write_text("A = 1\n")
    os.utime(a, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert fingerprint() == first
    (root / "pkg" / "c.py").write_text("")
    added = fingerprint()
    assert added not in (first, edited) and added == fingerprint(off=True)
    (root / "pkg" / "c.py").unlink()
    (root / "pkg" / "sub" / "b.py").unlink()
    assert fingerprint() not in (first, edited, added)
