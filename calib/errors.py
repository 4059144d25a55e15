"""Errors that reach the operator as one clear line.

Every error robocal raises on bad input is a :class:`RobocalError` whose message names what is wrong and where
(file, key, line, device, command).  The command line prints ``robocal: error: <message>`` and exits with status 2;
it never shows a traceback for these.
"""
from __future__ import annotations


class RobocalError(Exception):
    """Base class: the message is a single line meant for the operator."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


class ConfigError(RobocalError):
    """A robot description, scenario or settings file is malformed (names the file and the key)."""

    def __init__(self, source: str, key: str | None, problem: str):
        where = f"{source}: {key}" if key else source
        super().__init__(f"{where}: {problem}")
        self.source, self.key, self.problem = source, key, problem


class GeometryError(RobocalError):
    """A measurement geometry cannot be solved (parallel sight lines, a point behind a station, ...)."""
