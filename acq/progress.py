"""A progress display for searches that take more than a second (rich, on stderr, only on a terminal)."""
from __future__ import annotations

import sys
import time
from contextlib import contextmanager


@contextmanager
def progress_display(title: str, after_s: float = 1.0):
    """Yield a callback ``update(stage, fraction)``; a bar appears once the work has run for ``after_s``."""
    if not sys.stderr.isatty():
        yield lambda stage, fraction: None
        return
    # rich costs ~0.1 s at start-up (robocal plan loads this module); only a bar on a terminal needs it
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    start = time.monotonic()
    bar = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>3.0f}%"),
                   TimeElapsedColumn(), transient=True, console=None, redirect_stdout=False)
    state = {"task": None, "started": False}

    def update(stage: str, fraction: float):
        if not state["started"] and time.monotonic() - start > after_s:
            bar.start()
            state["started"] = True
            state["task"] = bar.add_task(f"{title}: {stage}", total=1.0)
        if state["started"]:
            bar.update(state["task"], completed=fraction, description=f"{title}: {stage}")

    try:
        yield update
    finally:
        if state["started"]:
            bar.stop()
