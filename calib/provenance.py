"""Where a result came from: the code, the robot description, the scenario and the command line (contract C6).

Every reprocess, identify and diagnose output carries :func:`provenance` under the key ``provenance`` and shows it in
its HTML report (:func:`provenance_html`), so that a number in a report can be traced to the code and the inputs that
made it, and recomputed.  Files are identified by the SHA-256 of their bytes (``sha256sum FILE`` gives the same).
"""
from __future__ import annotations

import hashlib
import html
import shlex
import subprocess
import sys
from importlib import resources
from pathlib import Path

#: shipped files a description or scenario may name instead of a path ("puma560.toml (default)", "default")
_SHIPPED = {"default_robot": "puma560.toml", "default_scenario": "twin_default.toml"}


def robocal_version() -> str:
    """The installed robocal version ("0+unknown" when running from a source tree without package metadata)."""
    try:
        # importlib.metadata costs ~30-60 ms at import; only a written record asks the version
        from importlib.metadata import version
        return version("robocal")
    except Exception:          # pragma: no cover - no metadata
        return "0+unknown"


def git_commit() -> str | None:
    """The commit of the source tree robocal runs from, with ``+dirty`` when it has uncommitted changes; None when
    it is not a git checkout (an installed package) or git is unavailable."""
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5)
        if head.returncode != 0:
            return None
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=here,
                               capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip() + ("+dirty" if dirty.returncode == 0 and dirty.stdout.strip() else "")


def file_sha256(path_or_source: str | Path | None, default: str | None = None) -> str | None:
    """SHA-256 of a description file: a path, the name of a shipped file in ``calib/data`` (as a description's
    ``source`` gives it, e.g. "puma560.toml (default)"), or "default" for ``default``; None when there is none."""
    if path_or_source is None or str(path_or_source) == "default":
        if default is None:
            return None
        return hashlib.sha256((resources.files("calib") / "data" / default).read_bytes()).hexdigest()
    p = Path(str(path_or_source))
    if p.is_file():
        return hashlib.sha256(p.read_bytes()).hexdigest()
    shipped = resources.files("calib") / "data" / str(path_or_source).split(" (")[0]
    if shipped.is_file():
        return hashlib.sha256(shipped.read_bytes()).hexdigest()
    return None


def command_line(argv: list[str] | None = None) -> str:
    """The command as typed (``robocal`` for the program), quoted so that it can be pasted into a shell."""
    argv = list(sys.argv if argv is None else argv)
    return shlex.join(["robocal", *argv[1:]]) if argv else "robocal"


def provenance(robot_path: str | Path | None = None, scenario_path: str | Path | None = None,
               argv: list[str] | None = None) -> dict:
    """The provenance block of an output.

    ``robot_path``: the description file used (None: the shipped Puma 560); ``scenario_path``: the twin scenario
    (None: no scenario was involved; "default": the shipped default); ``argv``: the command line (default
    ``sys.argv``).
    """
    return {
        "robocal_version": robocal_version(),
        "git_commit": git_commit(),
        "robot_sha256": file_sha256(robot_path, _SHIPPED["default_robot"]),
        "scenario_sha256": file_sha256(scenario_path, _SHIPPED["default_scenario"]) if scenario_path else None,
        "command_line": command_line(argv),
    }


_LABELS = (("robocal_version", "robocal"), ("git_commit", "commit"), ("robot_sha256", "robot description SHA-256"),
           ("scenario_sha256", "scenario SHA-256"), ("command_line", "command"))


def provenance_html(prov: dict | None) -> str:
    """A small footer block for an HTML report (empty without provenance)."""
    if not prov:
        return ""
    rows = "".join(f"<tr><td>{label}</td><td><code>{html.escape(str(prov.get(key)))}</code></td></tr>"
                   for key, label in _LABELS if key in prov)
    return f"<footer><h2>Provenance</h2><table class='provenance'>{rows}</table></footer>"
