"""Importing a third-party checker of the ``dev`` extra (Pinocchio, GeoComPy): a test that compares robocal with
software nobody here wrote must not pass by skipping where that software is meant to be installed.

:func:`require` imports the module; when it is missing it fails the test if the ``dev`` extra is otherwise installed
(its other packages are present: the checker was left out by mistake), and skips only in a bare environment."""
from __future__ import annotations

import importlib
from importlib import metadata

import pytest

#: packages only the dev extra brings (pyproject.toml): their presence says the extra is installed
DEV_ONLY = ("hypothesis", "pytest-textual-snapshot")


def dev_extra_installed() -> bool:
    try:
        return all(metadata.version(d) for d in DEV_ONLY)
    except metadata.PackageNotFoundError:
        return False


def require(module: str, distribution: str):
    """The imported ``module`` (from the dev extra's ``distribution``), or a failed / skipped test (see above)."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        if dev_extra_installed():
            pytest.fail(f"{module} ({distribution}, in the dev extra) does not import although the dev extra is "
                        f"installed: {exc}")
        pytest.skip(f"{module} not installed (pip install -e .[dev])")
