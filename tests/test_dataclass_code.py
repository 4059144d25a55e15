"""Dataclass methods from the kept table (app.dataclass_code) are the ones dataclasses compiles itself: the same code,
annotations, defaults and behaviour, for robocal's own classes in a fresh process as for every kind of field here;
a damaged or absent table is compiled afresh, an unchanged one compiles nothing."""
from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import types
from pathlib import Path
from typing import ClassVar

import pytest

from app import dataclass_code

ROOT = Path(__file__).resolve().parents[1]


def shape(code: types.CodeType) -> tuple:
    """Everything of a code object that running it or reading a traceback could see (nested code too)."""
    return (code.co_code, tuple(shape(c) if isinstance(c, types.CodeType) else (type(c), c) for c in code.co_consts),
            code.co_names, code.co_varnames, code.co_freevars, code.co_cellvars, code.co_filename, code.co_name,
            code.co_qualname, code.co_firstlineno, code.co_flags, code.co_argcount, code.co_kwonlyargcount,
            code.co_posonlyargcount, code.co_linetable, code.co_exceptiontable)


def methods(cls) -> dict:
    """The methods dataclasses wrote for ``cls``: name -> (code shape, annotations, defaults, keyword defaults)."""
    out = {}
    for name, f in vars(cls).items():
        f = getattr(f, "__wrapped__", f)                # __repr__ is wrapped by reprlib's recursion guard
        if isinstance(f, types.FunctionType) and f.__code__.co_filename == "<string>":
            out[name] = (shape(f.__code__), {k: repr(v) for k, v in f.__annotations__.items()}, repr(f.__defaults__),
                         repr(f.__kwdefaults__), f.__qualname__)
    return out


def make_classes() -> list[type]:
    """Dataclasses of every kind dataclasses writes differently: frozen, defaults and factories, order, slots,
    keyword-only fields, class and init-only variables, post-init, inheritance."""
    @dataclasses.dataclass(frozen=True)
    class Point:
        x_mm: float
        y_mm: float = 0.0
        tags: tuple = ()

    @dataclasses.dataclass(order=True)
    class Mutable:
        n: int
        items: list = dataclasses.field(default_factory=list)
        limit: ClassVar[int] = 3
        scale: dataclasses.InitVar[float] = 1.0

        def __post_init__(self, scale):
            self.n = int(self.n * scale)

    @dataclasses.dataclass(slots=True, kw_only=True)
    class Slotted:
        a: int
        b: str = "b"

    @dataclasses.dataclass(frozen=True)
    class Child(Point):
        z_mm: float = 1.0
        note: str = dataclasses.field(default="", compare=False, repr=False)
    return [Point, Mutable, Slotted, Child]


@pytest.fixture
def table(tmp_path, monkeypatch):
    """A table at a file of its own, given to the dataclasses module for the test only."""
    t = dataclass_code.CodeTable(tmp_path / "table.marshal")
    monkeypatch.setattr(dataclasses, "exec", t.exec, raising=False)
    return t


def test_classes_made_through_the_table_are_the_classes_made_without(table, monkeypatch):
    plain = [methods(c) for c in _without_table(monkeypatch)]
    monkeypatch.setattr(dataclasses, "exec", table.exec, raising=False)
    first = make_classes()
    assert [methods(c) for c in first] == plain and table.new > 10
    table.write()
    again = dataclass_code.CodeTable(table.path)                # the next run: read back, nothing compiled
    monkeypatch.setattr(dataclasses, "exec", again.exec, raising=False)
    kept = make_classes()
    assert [methods(c) for c in kept] == plain and again.new == 0 and again.used == table.used
    point, mutable, slotted, child = kept
    assert point(1.0) == point(1.0, 0.0, ()) and hash(point(1.0)) == hash(point(1.0))
    assert repr(point(2.0, 3.0)).endswith("Point(x_mm=2.0, y_mm=3.0, tags=())")
    with pytest.raises(dataclasses.FrozenInstanceError):
        point(1.0).x_mm = 2.0
    assert mutable(2, scale=2.5).n == 5 and mutable(1) < mutable(2) and mutable(1).items is not mutable(1).items
    with pytest.raises(TypeError):
        slotted(1)
    assert slotted(a=1).b == "b" and not hasattr(slotted(a=1), "__dict__")
    assert child(1.0, note="x") == child(1.0, note="y") and "note" not in repr(child(1.0))


def _without_table(monkeypatch) -> list[type]:
    monkeypatch.delattr(dataclasses, "exec", raising=False)
    return make_classes()


@pytest.mark.parametrize("damage", [b"", b"not marshal", None])
def test_a_damaged_or_foreign_table_is_compiled_afresh(tmp_path, monkeypatch, damage):
    import marshal
    path = tmp_path / "table.marshal"
    path.write_bytes(marshal.dumps({"text": 3}) if damage is None else damage)
    t = dataclass_code.CodeTable(path)
    monkeypatch.setattr(dataclasses, "exec", t.exec, raising=False)
    plain = make_classes()
    assert t.new > 10
    monkeypatch.delattr(dataclasses, "exec")
    assert [methods(c) for c in plain] == [methods(c) for c in make_classes()]


def test_off_keeps_nothing(monkeypatch):
    monkeypatch.setenv("ROBOCAL_CACHE_DIR", "off")
    assert dataclass_code.table_path() is None
    t = dataclass_code.CodeTable(None)
    monkeypatch.setattr(dataclasses, "exec", t.exec, raising=False)
    make_classes()
    t.write()                                  # nothing to write to, nothing raised
    assert t.new > 10


_DUMP = """
import dataclasses, importlib, json, sys, types
sys.path.insert(0, %r)
from tests.test_dataclass_code import methods
if sys.argv[1] == "table":
    from app import dataclass_code
    table = dataclass_code.install()
mods = ["acq.session.setup_types", "acq.session.plan_doc", "acq.session.steps", "acq.encoders.sample", "calib.robot",
        "calib.kinds", "acq.session.runner"]
out = {}
for m in mods:
    for name, obj in vars(importlib.import_module(m)).items():
        if isinstance(obj, type) and dataclasses.is_dataclass(obj) and obj.__module__ == m:
            out[m + "." + name] = repr(methods(obj))
print(json.dumps({"classes": out, "new": table.new if sys.argv[1] == "table" else None}))
"""


def _dump(mode: str, cache: Path | str) -> dict:
    env = dict(os.environ, ROBOCAL_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", _DUMP % str(ROOT), mode], capture_output=True, text=True, env=env,
                       timeout=120, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_robocals_own_dataclasses_from_a_kept_table_are_the_ones_compiled(tmp_path):
    """Fresh processes: robocal's classes made without the table, with an empty one (compiled, then written at exit)
    and with the table read back (nothing compiled) have the same methods, code object for code object."""
    plain = _dump("plain", "off")["classes"]
    first, second = _dump("table", tmp_path), _dump("table", tmp_path)
    assert len(plain) > 20 and first["classes"] == plain and second["classes"] == plain
    assert first["new"] > 50 and second["new"] == 0
    assert len(list(tmp_path.glob("dataclass-code-*.marshal"))) == 1


def test_a_table_grown_too_large_keeps_this_runs_methods(table, monkeypatch):
    make_classes()
    table.write()
    monkeypatch.setattr(dataclass_code, "MAX_METHODS", 5)
    later = dataclass_code.CodeTable(table.path)
    monkeypatch.setattr(dataclasses, "exec", later.exec, raising=False)

    @dataclasses.dataclass
    class Other:
        one_field: int
    later.write()
    reread = dataclass_code.CodeTable(table.path)
    reread.code("x = 1")
    assert set(reread.codes) == later.used | {"x = 1"} and len(later.used) == 3


def test_two_processes_writing_the_table_keep_each_others_methods(tmp_path):
    """The demo's recorder and its reduction worker share one table and make different classes: each write keeps
    what the other wrote meanwhile (else every run would compile again what the other process dropped)."""
    path = tmp_path / "table.marshal"
    recorder, worker = dataclass_code.CodeTable(path), dataclass_code.CodeTable(path)
    recorder.code("a = 1")
    worker.code("b = 2")                        # both read the (empty) table before either wrote
    recorder.write()
    worker.write()
    reread = dataclass_code.CodeTable(path)
    reread.code("a = 1")
    assert set(reread.codes) == {"a = 1", "b = 2"} and reread.new == 0
