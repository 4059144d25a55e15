"""Loading a robot description from a file: the one entry every ``--robot`` goes through.

A ``.urdf`` is imported (:func:`calib.urdf.robot_from_urdf`), a TOML with ``urdf = ...`` is a calibration description
wrapping a URDF (:mod:`calib.description`), any other TOML a DH description (:mod:`calib.robot`).  Apart from
:mod:`calib.robot` so that the Robot itself knows none of the formats built on it.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

from .description import build_description
from .robot import Robot, parse_robot, robot_from_table
from .tomlspec import Checker
from .urdf import robot_from_urdf


class RobotPath(str):
    """A ``--robot`` argument with the chain cut of ``--base-link`` / ``--tip-link`` (used by URDF descriptions).

    A ``str`` so that every command passing ``args.robot`` to :func:`load_robot` gets the cut without knowing of it.
    """

    def __new__(cls, path: str, base_link: str | None = None, tip_link: str | None = None):
        obj = super().__new__(cls, path)
        obj.base_link, obj.tip_link = base_link, tip_link
        return obj


def load_robot(path: str | Path | None = None, base_link: str | None = None, tip_link: str | None = None) -> Robot:
    """Load a robot description: ``None`` gives the shipped Puma 560 of the thesis; a ``.urdf`` file is imported
    (:func:`robot_from_urdf`); a TOML file with ``urdf = ...`` is a calibration description wrapping a URDF
    (:mod:`calib.description`); any other TOML is a DH description (this module's format)."""
    if path is None:
        ref = resources.files("calib") / "data" / "puma560.toml"
        return parse_robot(ref.read_text(encoding="utf-8"), "puma560.toml (default)")
    base_link = base_link or getattr(path, "base_link", None)
    tip_link = tip_link or getattr(path, "tip_link", None)
    if str(path).lower().endswith(".urdf"):
        return robot_from_urdf(path, base_link, tip_link)
    chk, data = Checker.load(path)
    if "urdf" in data:
        return build_description(chk, data, Path(path), base_link, tip_link)
    if base_link or tip_link:
        chk.fail(None, "--base-link and --tip-link apply to URDF descriptions only")
    return robot_from_table(chk, data)
