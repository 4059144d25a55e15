"""Reading a JSON file the operator gave us: one clear line for a missing file or broken JSON, never a traceback."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .errors import RobocalError


def read_json(path: str | Path, required: tuple[str, ...] = ()) -> Any:
    """The parsed document; ``required`` keys must be present (the document must then be an object)."""
    src = str(path)
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RobocalError(f"{src}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RobocalError(f"{src}: cannot read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise RobocalError(f"{src}: not valid JSON: line {exc.lineno}: {exc.msg}") from None
    if required:
        if not isinstance(doc, dict):
            raise RobocalError(f"{src}: expected a JSON object")
        for key in required:
            if key not in doc:
                raise RobocalError(f"{src}: key {key!r} is missing")
    return doc
