"""Reading a JSON file the operator gave us: one clear line for a missing file, broken JSON or a document that does
not follow its schema -- never a traceback.

The whole document is checked before anything uses it.  The structure is a JSON Schema (the ``jsonschema`` library:
declarative, and its error paths name the exact key), and a message reads ``FILE: parameters[3].value: what is
wrong``.  NaN and Infinity (which Python's json module accepts) are refused, and so is a document nested too deeply for the
parser (a RecursionError).
"""
from __future__ import annotations

import functools
import json
import math
from pathlib import Path
from typing import Any

from .errors import RobocalError
from .textin import read_text

#: a finite JSON number that stays finite through products and squares (the model's arithmetic)
FINITE = {"type": "number", "finite": True, "minimum": -1e12, "maximum": 1e12}


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number (write a finite number)")


def parse_json(text: str, src: str, allow_nonfinite: bool = False) -> Any:
    """Parse JSON text (an optional BOM is skipped); errors name ``src`` with the line and column.

    ``allow_nonfinite``: accept NaN/Infinity (robocal's own documents carry them in informative keys, e.g. a
    condition number); a schema's ``"finite": true`` then refuses them where a value is used."""
    if not isinstance(text, str):
        raise RobocalError(f"{src}: not JSON text (got {type(text).__name__})")
    text = text.removeprefix("\ufeff")
    try:
        return json.loads(text, **({} if allow_nonfinite else {"parse_constant": _no_constant}))
    except json.JSONDecodeError as exc:
        raise RobocalError(f"{src}: line {exc.lineno}, column {exc.colno}: not valid JSON: {exc.msg}") from None
    except RecursionError:
        raise RobocalError(f"{src}: nested too deeply: not a robocal document") from None
    except ValueError as exc:  # NaN/Infinity, an integer beyond 4300 digits
        raise RobocalError(f"{src}: not valid JSON: {' '.join(str(exc).split())[:160]}") from None


def json_path(parts) -> str:
    """``parameters[3].value`` from a schema error's path."""
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out


@functools.cache
def _validator_class():
    """Draft 2020-12 with two more keywords, ``"finite": true`` and ``"notNaN": true`` (JSON Schema's ``number``
    lets NaN and Infinity through)."""
    # jsonschema costs ~0.1-0.2 s at import; only a document being checked needs it
    import jsonschema

    def finite(validator, wanted, instance, schema):
        if wanted and isinstance(instance, float) and not math.isfinite(instance):
            yield jsonschema.ValidationError(f"{instance!r} is not a finite number")

    def not_nan(validator, wanted, instance, schema):
        if wanted and isinstance(instance, float) and math.isnan(instance):
            yield jsonschema.ValidationError("NaN is not a number")

    return jsonschema.validators.extend(jsonschema.Draft202012Validator, {"finite": finite, "notNaN": not_nan})


#: documents already found valid: (id of the schema, canonical JSON text) -> the schema (held, so its id stays its own)
_VALID: dict[tuple[int, str], dict] = {}
_VALID_MAX = 64


def _plain(doc: Any) -> bool:
    """Only JSON's own types (dict with str keys, list, str, int, float, bool, None): then the canonical text names
    the document exactly (a tuple, which the schema does not take for an array, would print as one)."""
    if isinstance(doc, dict):
        return all(isinstance(k, str) and _plain(v) for k, v in doc.items())
    if isinstance(doc, list):
        return all(_plain(v) for v in doc)
    return doc is None or isinstance(doc, (str, int, float))


def _memo_key(doc: Any, schema: dict) -> tuple[int, str] | None:
    if not _plain(doc):
        return None
    try:
        return id(schema), json.dumps(doc, sort_keys=True, allow_nan=True)
    except (TypeError, ValueError, RecursionError):
        return None


def vouch(doc: Any, schema: dict) -> Any:
    """``doc``, entered as valid against ``schema`` without checking it: for a document robocal made itself from
    checked inputs (the demo's own bench, a plan section it built, the model its reduction identified), so that
    typing it again, storing it and reading it back costs no check -- and a run that reads no file of the user's no
    ``jsonschema`` import (0.1-0.2 s of ``robocal demo``).  Files and anything a user gives are still checked where
    they come in; tests check the vouched documents against the schemas."""
    key = _memo_key(doc, schema)
    if key is not None:
        if len(_VALID) >= _VALID_MAX:
            _VALID.pop(next(iter(_VALID)))
        _VALID[key] = schema
    return doc


def check_schema(doc: Any, schema: dict, src: str) -> Any:
    """``doc`` if it follows ``schema``; otherwise one line naming the first offending key (the deepest first).

    A document already found valid against the same schema object is not checked again (why: a session's set-up is
    read back from its database and typed several times per run; each full check cost ~25 ms)."""
    key = _memo_key(doc, schema)
    if key is not None and _VALID.get(key) is schema:
        return doc
    # jsonschema: lazy, as in _validator_class (only reached when a document is checked)
    import jsonschema
    validator = _validator_class()(schema)
    error = jsonschema.exceptions.best_match(validator.iter_errors(doc))
    if error is None:
        if key is not None:
            if len(_VALID) >= _VALID_MAX:
                _VALID.pop(next(iter(_VALID)))
            _VALID[key] = schema
        return doc
    where = json_path(error.absolute_path) or "document"
    message = error.message if len(error.message) <= 160 else error.message[:157] + "..."
    raise RobocalError(f"{src}: {where}: {message}")


def read_json(path: str | Path, required: tuple[str, ...] = (), schema: dict | None = None,
              allow_nonfinite: bool = False) -> Any:
    """The parsed document; ``required`` keys must be present (the document must then be an object); ``schema``
    (a JSON Schema) checks the whole document."""
    src = str(path)
    doc = parse_json(read_text(path), src, allow_nonfinite)
    if required:
        if not isinstance(doc, dict):
            raise RobocalError(f"{src}: expected a JSON object")
        for key in required:
            if key not in doc:
                raise RobocalError(f"{src}: key {key!r} is missing")
    if schema is not None:
        check_schema(doc, schema, src)
    return doc
