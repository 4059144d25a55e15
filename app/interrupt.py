"""What an interrupted session tells the operator: how many steps are kept, where, and the command that resumes.

Ctrl-C (SIGINT), a closed terminal (SIGHUP) and a device fault all end a session between two committed steps -- the
store commits a step in one transaction, so nothing accepted is ever lost -- and a bare "interrupted" left the
operator guessing whether an hour of sightings was gone.  :func:`kept_text` is the one wording every front end prints
(``robocal demo``, ``robocal session`` and its TUI), :func:`hangups_interrupt` makes a closed terminal end the
session the way Ctrl-C does instead of killing it mid-step, and :func:`say` prints even when the terminal is gone.
"""
from __future__ import annotations

import shlex
import signal
import sys
import threading
from contextlib import contextmanager
from typing import Iterator

EXIT_INTERRUPTED, EXIT_HUNG_UP = 130, 129


class HungUp(KeyboardInterrupt):
    """The terminal was closed (SIGHUP): handled like Ctrl-C, with its own exit status."""


def exit_status(exc: BaseException) -> int:
    return EXIT_HUNG_UP if isinstance(exc, HungUp) else EXIT_INTERRUPTED


@contextmanager
def hangups_interrupt() -> Iterator[None]:
    """Within the block a SIGHUP raises :class:`HungUp` in the main thread, as SIGINT raises KeyboardInterrupt."""
    if not hasattr(signal, "SIGHUP") or threading.current_thread() is not threading.main_thread():
        yield
        return

    def hung_up(signum, frame):
        raise HungUp()

    old = signal.signal(signal.SIGHUP, hung_up)
    try:
        yield
    finally:
        signal.signal(signal.SIGHUP, old)


def command_line(words: list[str]) -> str:
    """A command as the operator types it again (quoted where the shell needs it)."""
    return shlex.join(str(w) for w in words)


def kept_text(saved: int, total: int, db: str, resume: str) -> str:
    """``12 of 176 steps saved in cell.db`` and the exact command that resumes at the first step not saved."""
    return f"{saved} of {total} steps saved in {db}\nresume with: {resume}"


def report_text(db: str, out_dir: str = "report/") -> str:
    """The command that makes the report of a session database."""
    return f"report with: {command_line(['robocal', 'reprocess', db, '--report', out_dir])}"


def say(text: str) -> None:
    """Print to stderr; a terminal already closed (SIGHUP) is no error -- whoever redirected stderr still gets it."""
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass
