"""An on-disk cache for pure computations a short command repeats on every run with the same inputs.

Why: ``robocal demo`` chooses its pose set from random candidates checked by the pre-flight (about 0.35 s of CPU of
a run that should take 2.5 s), and the choice is a pure function of the robot, the set-up and the seed.  The result
is kept under the user's cache folder, keyed by a hash of the inputs *and* of robocal's own source (every package:
the demo's pose choice runs code of ``app/``, ``sim/``, ``acq/`` and ``calib/``), so any change of the code that
computes it is a miss, never a stale answer.  A cache that cannot be
read or written is no cache (the value is computed; a folder that cannot be written is said once, as a warning, so a
slow run is explained); ``ROBOCAL_CACHE_DIR`` moves it, ``ROBOCAL_CACHE_DIR=off``
turns it off.
"""
from __future__ import annotations

import functools
import hashlib
import io
import json
import os
import warnings
from pathlib import Path
from typing import Callable

import numpy as np

from calib.fileio import atomic_write_bytes

from .cache_folder import cache_dir

_ROOT = Path(__file__).resolve().parents[1]
#: the source folders whose code the cached computations run (a change of any file there is a miss): every package,
#: so that moving code between them can never leave a stale answer (the layout move put the demo's pose choice in
#: app/ and its twin in sim/, outside the folders first listed here)
_SOURCES = ("acq", "app", "calib", "offline", "sim")


@functools.cache
def code_fingerprint() -> str:
    """SHA-256 of the sources the cached computations depend on: every package's ``.py`` files, path and content.

    Reading and hashing them all costs 80 M instructions (~25 ms), so the answer is kept as well, under the files'
    paths, sizes and modification times to the nanosecond -- what Python's own bytecode cache compares (to the
    second) before it runs a module: a run that finds every file as it was takes the kept answer after a walk and a
    stat per file; any edit, file added or removed reads the contents again."""
    files = _source_files()
    stats = hashlib.sha256()
    for rel, path in files:
        st = os.stat(path)
        stats.update(f"{rel}\0{st.st_size}\0{st.st_mtime_ns}\0".encode())
    kept = _entry("code-fingerprint", stats.digest(), "txt", fingerprint=False)
    if kept is not None:
        try:
            text = kept.read_text(encoding="ascii")
            if len(text) == 64 and all(c in "0123456789abcdef" for c in text):
                return text
        except (OSError, ValueError):                   # absent or damaged: read the sources
            pass
    h = hashlib.sha256()
    for rel, path in files:
        h.update(rel.encode())
        with open(path, "rb") as f:
            h.update(f.read())
    if kept is not None:
        _store(kept, h.hexdigest().encode())
    return h.hexdigest()


def _source_files() -> list[tuple[str, str]]:
    """(path from the tree's root, full path) of every ``.py`` file of :data:`_SOURCES`, in a fixed order."""
    out = []
    for folder in _SOURCES:
        for where, dirs, names in os.walk(os.path.join(_ROOT, folder)):
            dirs.sort()
            rel = os.path.relpath(where, _ROOT)
            out += [(os.path.join(rel, n), os.path.join(where, n)) for n in sorted(names) if n.endswith(".py")]
    return out


def cached_array(kind: str, inputs: bytes, compute: Callable[[], np.ndarray],
                 shape: tuple[int, ...] | None = None) -> np.ndarray:
    """``compute()``'s array, from the cache when this ``kind`` was computed for the same ``inputs`` (bytes that
    name them exactly) and the same source; computed and stored otherwise.  ``shape``: what a stored entry must be
    (a finite float array of it), else it is computed again -- a damaged or tampered file is never used."""
    path = _entry(kind, inputs, "npy")
    if path is None:
        return compute()
    try:
        kept = np.load(path, allow_pickle=False)
        if shape is None or (kept.shape == tuple(shape) and kept.dtype.kind == "f" and np.all(np.isfinite(kept))):
            return kept
    except (OSError, ValueError, EOFError):     # absent, or not a whole .npy (then computed and written again)
        pass
    value = np.asarray(compute())
    buf = io.BytesIO()
    np.save(buf, value, allow_pickle=False)
    _store(path, buf.getvalue())
    return value


def cached_json(kind: str, inputs: bytes, compute: Callable[[], dict]) -> dict:
    """``compute()``'s JSON document (a dict), from the cache as :func:`cached_array` keeps an array.  The answer
    is the document read back from its JSON text on a miss too, so the first run and the next ones hand their
    caller the very same value (a tuple computed is a list either way).  A stored entry that is not a JSON object
    is computed again."""
    path = _entry(kind, inputs, "json")
    if path is not None:
        try:
            kept = json.loads(path.read_bytes())
            if isinstance(kept, dict):
                return kept
        except (OSError, ValueError):             # absent, or not whole JSON
            pass
    text = json.dumps(compute()).encode()
    if path is not None:
        _store(path, text)
    return json.loads(text)


def _entry(kind: str, inputs: bytes, suffix: str, fingerprint: bool = True) -> Path | None:
    """Where the cache keeps ``kind`` for ``inputs`` and this source (``fingerprint``; None: the cache is off)."""
    folder = cache_dir()
    if folder is None:
        return None
    key = hashlib.sha256(b"\0".join([kind.encode(), code_fingerprint().encode() if fingerprint else b"", inputs]))
    return folder / f"{kind}-{key.hexdigest()[:32]}.{suffix}"


def _store(path: Path, data: bytes) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(path, data)
    except Exception as exc:    # a read-only or full disk: the value is still right, only not kept -- and said once
        _warn_unwritable(path.parent, exc)


_WARNED: set[Path] = set()


def _warn_unwritable(folder: Path, exc: Exception) -> None:
    """One warning per folder and process (the operator learns why every run recomputes, and how to move it)."""
    if folder in _WARNED:
        return
    _WARNED.add(folder)
    warnings.warn(f"cache folder {folder} cannot be written ({type(exc).__name__}: {exc}); computing without a cache "
                  "(ROBOCAL_CACHE_DIR=PATH moves it, ROBOCAL_CACHE_DIR=off turns it off)", stacklevel=3)
