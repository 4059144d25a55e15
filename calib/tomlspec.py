"""A small declarative checker for robocal's TOML files (robot descriptions, twin scenarios).

Why not a schema library: the files are small, and what the operator needs is one line that names the file and the
exact key (``puma.toml: joint[3].gear_ratio: must be a finite number, got nan``).  Each table is described by a dict of
:class:`Field`; unknown keys, missing keys, wrong types, NaN and out-of-range values are all reported that way.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .errors import ConfigError
from .textin import read_text


@dataclass(frozen=True)
class Field:
    """One key of a table: its kind, whether it is required, its default and its admissible range."""

    kind: str  # "number", "int", "bool", "str", "vector", "table", "tables", "matrix"
    required: bool = False
    default: Any = None
    min: float | None = None       # inclusive lower bound for numbers / every vector element
    max: float | None = None
    positive: bool = False         # strictly > 0
    length: int | None = None      # vector length
    max_abs: float = 1e15          # no robot or scenario number is larger: beyond, a typo (1e308) that would overflow
    help: str = ""


class Checker:
    """Reads a TOML file and checks its tables against field specs, raising :class:`ConfigError` on the first fault."""

    def __init__(self, source: str):
        self.source = source

    @classmethod
    def load(cls, path: str | Path) -> tuple["Checker", dict]:
        return cls.parse(read_text(path), str(path))

    @classmethod
    def parse(cls, text: str, source: str) -> tuple["Checker", dict]:
        try:
            data = tomllib.loads(text.removeprefix("\ufeff"))
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(source, None, f"not valid TOML: {exc}") from None
        except RecursionError:
            raise ConfigError(source, None, "not valid TOML: arrays or tables nested too deeply") from None
        except ValueError as exc:  # e.g. an integer beyond Python's 4300-digit conversion limit
            raise ConfigError(source, None, f"not valid TOML: {' '.join(str(exc).split())[:120]}") from None
        return cls(source), data

    def fail(self, key: str | None, problem: str) -> None:
        raise ConfigError(self.source, key, problem)

    def table(self, data: Any, spec: dict[str, Field], where: str) -> dict[str, Any]:
        """Check one table; return a dict with every spec key (defaults filled in)."""
        if not isinstance(data, dict):
            self.fail(where, "must be a table")
        unknown = sorted(set(data) - set(spec))
        if unknown:
            known = ", ".join(sorted(spec))
            self.fail(self._join(where, unknown[0]), f"unknown key (known keys: {known})")
        out: dict[str, Any] = {}
        for name, field in spec.items():
            key = self._join(where, name)
            if name not in data:
                if field.required:
                    self.fail(key, "missing")
                out[name] = field.default
                continue
            out[name] = self.value(data[name], field, key)
        return out

    def value(self, raw: Any, field: Field, key: str) -> Any:
        kind = field.kind
        if kind == "number":
            return self._number(raw, field, key)
        if kind == "int":
            if isinstance(raw, bool) or not isinstance(raw, int):
                self.fail(key, f"must be a whole number, got {_short(raw)}")
            if abs(raw) > 2 ** 53:
                self.fail(key, f"must be a whole number of magnitude at most 2**53, got {_short(raw)}")
            self._range(float(raw), field, key)
            return raw
        if kind == "bool":
            if not isinstance(raw, bool):
                self.fail(key, f"must be true or false, got {_short(raw)}")
            return raw
        if kind == "str":
            if not isinstance(raw, str):
                self.fail(key, f"must be a string, got {_short(raw)}")
            return raw
        if kind == "vector":
            if not isinstance(raw, list):
                self.fail(key, f"must be a list of numbers, got {_short(raw)}")
            if field.length is not None and len(raw) != field.length:
                self.fail(key, f"must have {field.length} numbers, got {len(raw)}")
            return [self._number(v, field, f"{key}[{i}]") for i, v in enumerate(raw)]
        if kind == "matrix":
            if not isinstance(raw, list) or not raw or not all(isinstance(r, list) for r in raw):
                self.fail(key, "must be a list of rows (lists of numbers)")
            ragged = [i for i, r in enumerate(raw) if len(r) != len(raw[0])]
            if ragged:
                self.fail(f"{key}[{ragged[0]}]", f"has {len(raw[ragged[0]])} numbers, row 0 has {len(raw[0])}: "
                                                  "every row needs the same length")
            n = field.length
            if n is not None and (len(raw) != n or any(len(r) != n for r in raw)):
                self.fail(key, f"must be a {n}x{n} matrix")
            return [[self._number(v, field, f"{key}[{i}][{j}]") for j, v in enumerate(r)] for i, r in enumerate(raw)]
        if kind in ("table", "tables"):
            return raw  # checked by the caller with its own spec
        raise AssertionError(f"unknown field kind {kind}")

    def _number(self, raw: Any, field: Field, key: str) -> float:
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            self.fail(key, f"must be a number, got {_short(raw)}")
        try:
            value = float(raw)
        except OverflowError:
            value = math.inf
        if not math.isfinite(value):
            self.fail(key, f"must be a finite number, got {_short(raw)}")
        self._range(value, field, key)
        return value

    def _range(self, value: float, field: Field, key: str) -> None:
        if abs(value) > field.max_abs:
            self.fail(key, f"{value:g} is beyond +-{field.max_abs:g}: a typing mistake?")
        if field.positive and not value > 0:
            self.fail(key, f"must be positive, got {value:g}")
        if field.min is not None and value < field.min:
            self.fail(key, f"must be >= {field.min:g}, got {value:g}")
        if field.max is not None and value > field.max:
            self.fail(key, f"must be <= {field.max:g}, got {value:g}")

    @staticmethod
    def _join(where: str, name: str) -> str:
        return f"{where}.{name}" if where else name


def _short(raw: Any) -> str:
    """``repr`` cut to a readable length (a fuzzed file may hold a 10,000-digit number or a huge table)."""
    text = repr(raw) if not isinstance(raw, int) or abs(raw) < 10 ** 30 else f"an integer of {len(str(abs(raw)))} digits"
    return text if len(text) <= 60 else text[:57] + "..."


def check_each(checker: Checker, items: Any, spec: dict[str, Field], where: str,
               build: Callable[[dict[str, Any], str], Any]) -> list[Any]:
    """Check an array of tables (``[[joint]]``) item by item, naming each as ``where[i]`` (1-based)."""
    if not isinstance(items, list):
        checker.fail(where, "must be an array of tables")
    out = []
    for i, item in enumerate(items, start=1):
        key = f"{where}[{i}]"
        out.append(build(checker.table(item, spec, key), key))
    return out
