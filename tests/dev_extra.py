"""Importing a third-party checker of the ``dev`` extra (Pinocchio, GeoComPy): a test that compares robocal with
software nobody here wrote must not pass by skipping where that software is meant to be installed.

:func:`require` imports the module; when it is missing it fails the test if the ``dev`` extra is otherwise installed
(its other packages are present: the checker was left out by mistake), and skips only in a bare environment."""
from __future__ import annotations

import importlib
import re
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"


def dev_extra() -> list[str]:
    """The distributions the ``dev`` extra lists in pyproject.toml (names without their version bounds)."""
    doc = tomllib.loads(PYPROJECT.read_text(encoding="utf-8"))
    return [re.split(r"[<>=!~\[; ]", d, maxsplit=1)[0] for d in doc["project"]["optional-dependencies"]["dev"]]


def dev_extra_installed(missing: str = "") -> bool:
    """Whether the dev extra is installed: every distribution it lists but ``missing`` (the one that failed to
    import) is present."""
    try:
        return all(metadata.version(d) for d in dev_extra() if d != missing)
    except metadata.PackageNotFoundError:
        return False


def require(module: str, distribution: str):
    """The imported ``module`` (from the dev extra's ``distribution``), or a failed / skipped test (see above)."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if distribution in dev_extra() and dev_extra_installed(distribution):
            pytest.fail(f"{module} ({distribution}, in the dev extra) does not import although the dev extra is "
                        f"installed: {exc}")
        pytest.skip(f"{module} not installed (pip install -e .[dev])")
