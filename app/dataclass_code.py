"""Dataclass methods compiled once per interpreter, not on every start of ``robocal``.

Why: CPython's :mod:`dataclasses` writes each method it generates (``__init__``, ``__repr__``, ``__eq__``, a frozen
class's ``__setattr__``, ...) as source text and runs it with :func:`exec` as the class is made: a compilation per
method.  ``robocal demo`` makes about 115 dataclasses as it imports its modules, about 450 compilations: 50-80 ms of
a start-up its speed target counts (``benchmarks/bench_demo.py``; 163 M of 1,287 M instructions of the demo's
imports, callgrind).  A method's text is a pure function of its class's fields, so the code compiled from it is
kept between runs, as Python keeps a module's bytecode.

How: :func:`install` gives the dataclasses module an ``exec`` of its own (a module global, found before the builtin)
that, for a source text, runs the code ``compile`` gives for that text -- what ``exec`` does with a text itself
(no future flags: the dataclasses module has none) -- looked up by the text in a table read from robocal's
cache folder (:func:`acq.cache_folder.cache_dir`) at the first class made, and written back at exit when a text
was new.  The table's name carries the interpreter's bytecode magic number (code objects are only read by the
interpreter that wrote them).  Nothing else of the dataclasses module changes; a class made with the table has the
methods made without it, code object for code object (``tests/test_dataclass_code.py``).  The cache off
(``ROBOCAL_CACHE_DIR=off``), unreadable or damaged: every text is compiled, as without this module.  The table is
trusted as Python trusts its own bytecode cache: both are code run from a folder of the user's.
"""
from __future__ import annotations

import atexit
import builtins
import dataclasses
import importlib.util
import marshal
import sys
import types
from pathlib import Path

from acq.cache_folder import cache_dir
from calib.fileio import atomic_write_bytes

#: the most methods the table keeps (the demo uses about 450; reading 2,000 takes about 10 ms); a larger one is written
#: back with this run's methods only (code that changed often)
MAX_METHODS = 2000


class CodeTable:
    """Compiled dataclass methods by their text, read from ``path`` on first use (None: kept in memory only).  The
    text itself is the key: no digest to compute (hashlib alone takes 7 ms to import), none that could collide."""

    def __init__(self, path: Path | None):
        self.path = path
        self.codes: dict[str, types.CodeType] | None = None
        self.used: set[str] = set()
        self.new = 0

    def exec(self, source, globals=None, locals=None, /):
        """:func:`exec`, a source text run as the code compiled from it (kept for the next text alike)."""
        if type(source) is str:
            source = self.code(source)
        return builtins.exec(source, globals, locals)

    def code(self, text: str) -> types.CodeType:
        if self.codes is None:
            self.codes = self._read()
        code = self.codes.get(text)
        if code is None:
            code = self.codes[text] = compile(text, "<string>", "exec", dont_inherit=True)
            self.new += 1
        self.used.add(text)
        return code

    def _read(self) -> dict:
        if self.path is None:
            return {}
        try:
            table = marshal.loads(self.path.read_bytes())
        except (OSError, EOFError, ValueError, TypeError):      # absent or damaged: compiled afresh
            return {}
        if not isinstance(table, dict) or not all(type(k) is str and type(v) is types.CodeType
                                                  for k, v in table.items()):
            return {}
        return table

    def write(self) -> None:
        """The table back to its file when a method was new, with what another process wrote there meanwhile (the
        demo's recorder and its reduction worker make different classes); this run's methods only when it grew too
        large."""
        if self.path is None or not self.new or self.codes is None:
            return
        keep = {**self._read(), **self.codes}
        if len(keep) > MAX_METHODS:
            keep = {k: self.codes[k] for k in self.used}
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_bytes(self.path, marshal.dumps(keep))
        except OSError:                 # a read-only or full disk: the next run compiles again, nothing is wrong
            pass
        self.new = 0


def table_path() -> Path | None:
    """This interpreter's table in the cache folder (None: the cache is off)."""
    folder = cache_dir()
    if folder is None:
        return None
    return folder / f"dataclass-code-{sys.implementation.cache_tag}-{importlib.util.MAGIC_NUMBER.hex()}.marshal"


_INSTALLED: CodeTable | None = None


def install() -> CodeTable | None:
    """Compile dataclass methods through the kept table from now on, in this process (once)."""
    global _INSTALLED
    if _INSTALLED is None and "exec" not in vars(dataclasses):
        _INSTALLED = CodeTable(table_path())
        dataclasses.exec = _INSTALLED.exec
        atexit.register(_INSTALLED.write)
    return _INSTALLED
