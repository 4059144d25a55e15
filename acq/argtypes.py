"""Argument types for the command line: every option is checked when it is parsed, before any work starts.

Why at parse time: a long fit must never end in a traceback about its output directory, and a NaN or a negative rate
must never reach a server thread or a loop.  Each type is a callable for ``argparse``'s ``type=``; it raises
:class:`argparse.ArgumentTypeError` with a message that reads after the option name
(``--rate-hz must be positive, got '-5'``), which :mod:`app.cli` prints as one line with exit status 2.
"""
from __future__ import annotations

import argparse
import math
import re
import os
from pathlib import Path
from typing import Callable

STDOUT = "-"


def _fail(message: str, raw: str) -> argparse.ArgumentTypeError:
    return argparse.ArgumentTypeError(f"{message}, got {raw!r}")


def finite_float(raw: str) -> float:
    """A finite number (no NaN, no infinity, nothing that overflows to infinity such as ``1e400``)."""
    try:
        value = float(raw)
    except (TypeError, ValueError):
        raise _fail("must be a number", raw) from None
    if not math.isfinite(value):
        raise _fail("must be a finite number", raw)
    return value


def positive_float(raw: str) -> float:
    """A finite number > 0 (rates, durations, noise levels)."""
    value = finite_float(raw)
    if not value > 0:
        raise _fail("must be positive", raw)
    return value


def nonneg_float(raw: str) -> float:
    """A finite number >= 0 (a rate where 0 means off)."""
    value = finite_float(raw)
    if value < 0:
        raise _fail("must be zero or positive", raw)
    return value


def _integer(raw: str) -> int:
    text = str(raw).strip()
    if len(text) > 18:  # also keeps Python's 4300-digit int() limit and huge loops out
        raise _fail("must be a whole number of at most 18 digits", raw)
    try:
        return int(text)
    except ValueError:
        raise _fail("must be a whole number", raw) from None


def positive_int(raw: str) -> int:
    """A whole number >= 1 (counts, folds, draws)."""
    value = _integer(raw)
    if value < 1:
        raise _fail("must be at least 1", raw)
    return value


def nonneg_int(raw: str) -> int:
    """A whole number >= 0 (0 meaning none/off)."""
    value = _integer(raw)
    if value < 0:
        raise _fail("must be zero or positive", raw)
    return value


def any_int(raw: str) -> int:
    """A whole number (seeds); bounded length so it cannot be a denial of service."""
    return _integer(raw)


def seed_int(raw: str) -> int:
    """A random seed: a whole number 0 .. 2**32 - 1 (numpy's legacy seeding accepts no more)."""
    value = _integer(raw)
    if not 0 <= value < 2 ** 32:
        raise _fail("must be a whole number 0..4294967295", raw)
    return value


def int_range(low: int, high: int) -> Callable[[str], int]:
    """A whole number in ``low .. high`` (both inclusive)."""
    def check(raw: str) -> int:
        value = _integer(raw)
        if not low <= value <= high:
            raise _fail(f"must be a whole number {low}..{high}", raw)
        return value
    check.__name__ = f"int_{low}_{high}"
    return check


def float_range(low: float, high: float, *, low_open: bool = False, high_open: bool = False) -> Callable[[str], float]:
    """A finite number in the range; ``low_open``/``high_open`` exclude the end point."""
    def check(raw: str) -> float:
        value = finite_float(raw)
        above = value > low if low_open else value >= low
        below = value < high if high_open else value <= high
        if not (above and below):
            lo, hi = ("(" if low_open else "["), (")" if high_open else "]")
            raise _fail(f"must be in {lo}{low:g}, {high:g}{hi}", raw)
        return value
    check.__name__ = f"float_{low:g}_{high:g}"
    return check


def _writable_dir(directory: Path, raw: str, what: str) -> None:
    if not directory.exists():
        raise _fail(f"{what} directory {str(directory)!r} does not exist", raw)
    if not directory.is_dir():
        raise _fail(f"{str(directory)!r} is not a directory", raw)
    if not os.access(directory, os.W_OK | os.X_OK):
        raise _fail(f"{what} directory {str(directory)!r} is not writable", raw)


def output_file(raw: str) -> str:
    """A file to write: ``-`` (standard output) or a path whose directory exists and is writable, not a directory."""
    if raw == STDOUT:
        return raw
    if not raw:
        raise _fail("must be a file name", raw)
    path = Path(raw)
    if path.is_dir():
        raise _fail("is a directory, not a file", raw)
    _writable_dir(path.parent if str(path.parent) else Path("."), raw, "the output file's")
    if path.exists() and not os.access(path, os.W_OK):
        raise _fail("exists and is not writable", raw)
    return raw


def output_dir(raw: str) -> str:
    """A directory to write into: it exists and is writable, or it can be created (its nearest parent is writable)."""
    if not raw:
        raise _fail("must be a directory name", raw)
    path = Path(raw)
    if path.exists():
        if not path.is_dir():
            raise _fail("exists and is not a directory", raw)
        _writable_dir(path, raw, "the output")
        return raw
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    _writable_dir(parent, raw, "the nearest existing parent")
    return raw


def existing_file(raw: str) -> str:
    """A file to read: it exists, is a regular file (not a directory) and is readable."""
    path = Path(raw)
    if not path.exists():
        raise _fail("file not found", raw)
    if path.is_dir():
        raise _fail("is a directory, not a file", raw)
    if not os.access(path, os.R_OK):
        raise _fail("is not readable", raw)
    return raw


def effect_spec(raw: str) -> str:
    """An ``--effect KIND:FIELD:...`` text whose fields are finite numbers or joint names (one word; the effect
    registry checks the rest against the robot)."""
    kind, *fields = str(raw).split(":")
    if not kind:
        raise _fail("must start with an effect kind (KIND:FIELDS)", raw)
    for i, field in enumerate(fields, 1):
        try:
            value = float(field)
        except ValueError:
            if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", field):
                continue                                  # a joint's name
            raise _fail(f"field {i} must be a number or a joint name", raw) from None
        if not math.isfinite(value) or abs(value) > 1e6:
            raise _fail(f"field {i} must be a finite number of at most 1e6", raw)
    return raw


def add_force_argument(p) -> None:
    """``--force-implausible``: run a fit on data the plausibility checks refuse (:mod:`calib.plausibility`); each
    finding then is a named warning on stderr and in the JSON instead of an error."""
    p.add_argument("--force-implausible", action="store_true",
                   help="fit even when the data look implausible (units, joint count, too few distinct poses, "
                        "chi-square): each finding becomes a named warning")


def te_joints(raw: str) -> list[int]:
    """``--te-joints 2,3,4,6``: the joints whose transmission error a session measures, distinct joint numbers (which
    of them the robot has a planned range for is checked against its profile, :func:`app.demo.transmission_plan`)."""
    try:
        js = [int(v) for v in raw.split(",") if v.strip()]
    except ValueError:
        raise _fail("must be joint numbers separated by commas, e.g. 2,3,4,6", raw) from None
    if not js or len(set(js)) != len(js) or any(j < 1 for j in js):
        raise _fail("must list distinct joint numbers (1, 2, ...)", raw)
    return js


#: what ``--robot`` takes, the same words in every command (what :func:`calib.loading.load_robot` reads)
ROBOT_HELP = ("robot description: a DH TOML, a URDF (with --base-link/--tip-link to cut its chain) or a calibration "
              "description (a TOML wrapping a URDF)")


def add_robot_argument(p, default: str = "the thesis's Puma 560") -> None:
    """``--robot FILE``, described as everywhere else (:data:`ROBOT_HELP`), with the command's default."""
    p.add_argument("--robot", metavar="FILE", help=f"{ROBOT_HELP}; default: {default}")


def examples_text(examples: str) -> str:
    """The epilog of a ``--help``: its examples, one command a line, as typed."""
    lines = [ln.rstrip() for ln in examples.strip("\n").splitlines()]
    return "examples:\n" + "\n".join(f"  {ln}" for ln in lines) if lines else ""
