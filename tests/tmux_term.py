"""A real terminal for TUI tests: ``robocal`` started in a tmux pane of a given size, keys sent with ``send-keys``,
the screen read with ``capture-pane`` -- what an operator's terminal shows, not what the test harness renders."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time

import pytest

needs_tmux = pytest.mark.skipif(shutil.which("tmux") is None and not os.environ.get("CI"), reason="tmux not installed")


class Terminal:
    """``with Terminal(["session", "--emulate", ...], 80, 24) as t: t.wait_for("text"); t.keys("c")``."""

    def __init__(self, args: list[str], width: int, height: int):
        assert shutil.which("tmux"), "tmux is needed (the CI script installs it)"
        self.name = f"robocal-test-{os.getpid()}-{width}x{height}"
        cmd = " ".join([sys.executable, "-m", "app.cli", *args])
        # Textual sizes itself from COLUMNS/LINES when set (pytest sets them): let the pane decide
        env_cmd = f"cd {os.getcwd()} && env -u COLUMNS -u LINES TERM=xterm-256color {cmd}; sleep 30"
        subprocess.run(["tmux", "kill-session", "-t", self.name], capture_output=True)
        subprocess.run(["tmux", "new-session", "-d", "-s", self.name, "-x", str(width), "-y", str(height), env_cmd],
                       check=True)

    def __enter__(self) -> "Terminal":
        return self

    def __exit__(self, *exc) -> None:
        subprocess.run(["tmux", "kill-session", "-t", self.name], capture_output=True)

    def screen(self) -> str:
        # -J: a line the terminal wrapped (a long path printed after the TUI is gone) comes back whole
        return subprocess.run(["tmux", "capture-pane", "-p", "-J", "-t", self.name], capture_output=True,
                              text=True).stdout

    def keys(self, *keys: str, pause_s: float = 0.3) -> None:
        for k in keys:
            subprocess.run(["tmux", "send-keys", "-t", self.name, k])
            time.sleep(pause_s)

    def wait_for(self, *texts: str, timeout_s: float = 60.0) -> str:
        """The screen once every one of ``texts`` is on it (then once more, so it has settled)."""
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout_s:
            time.sleep(0.5)
            if all(t in self.screen() for t in texts):
                time.sleep(1.0)
                return self.screen()
        raise AssertionError(f"never showed {texts}:\n{self.screen()}")


def prose(screen: str) -> str:
    """The screen's words in reading order with frames and wrapping undone, to find a sentence a panel wrapped."""
    text = re.sub(r"[│╭╮╰╯─▔▁▂▃▄▅▆▇█▎▌]", " ", screen)
    return " ".join(text.split())


def panel_text(screen: str, marker: str) -> str:
    """The prose of the panel column that holds ``marker``: every line cut at the frames left and right of it (side
    panels stand beside the step's column at 160 columns), frames and wrapping undone."""
    lines = screen.splitlines()
    row = next(ln for ln in lines if marker in ln)
    at = row.index(marker)
    left = row.rfind("│", 0, at) + 1
    right = row.find("│", at)
    return prose("\n".join(ln[left:right] if right >= 0 else ln[left:] for ln in lines))
