"""Where robocal keeps what it caches between runs (:mod:`acq.cache`, :mod:`app.dataclass_code`).

Why a module of its own: the command line reads it before numpy is imported (the BLAS thread count is set first,
:mod:`app.cli`), so it imports the standard library only.
"""
from __future__ import annotations

import os
from pathlib import Path


def cache_dir() -> Path | None:
    """The cache folder, or None when turned off (``ROBOCAL_CACHE_DIR=off`` or empty)."""
    env = os.environ.get("ROBOCAL_CACHE_DIR")
    if env is not None:
        return None if env.strip().lower() in ("", "off", "0", "no") else Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "robocal"
