"""Interruptions say what was kept (issue 26, item 4): Ctrl-C, a closed terminal (SIGHUP) or a device fault prints how
many steps are saved, the database and the exact command that resumes -- and that command does resume."""
import asyncio
import re
import shlex
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from acq.session.steps import Step
from app.tui.app import RobocalApp, SessionHandle
from tests.fakes.still_runner import StillRunner
from tests.tmux_term import Terminal, needs_tmux


def _saved(db) -> int:
    try:
        with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as c:
            return c.execute("SELECT count(*) FROM step").fetchone()[0]
    except sqlite3.Error:
        return 0


def _robocal(words: list[str]) -> list[str]:
    assert words[0] == "robocal"
    return [sys.executable, "-m", "app.cli", *words[1:]]


def _interrupt_demo(tmp_path, sig) -> tuple[subprocess.CompletedProcess, str]:
    db = tmp_path / "d.db"
    p = subprocess.Popen(_robocal(["robocal", "demo", "--db", str(db)]), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    t0 = time.monotonic()
    while _saved(db) < 10 and time.monotonic() - t0 < 120 and p.poll() is None:
        time.sleep(0.05)
    p.send_signal(sig)
    out, err = p.communicate(timeout=60)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err), str(db)


@pytest.mark.parametrize("sig,status,words", [(signal.SIGINT, 130, "interrupted"),
                                              (signal.SIGHUP, 129, "the terminal closed")])
def test_an_interrupted_demo_says_what_it_kept_and_how_to_resume(tmp_path, sig, status, words):
    r, db = _interrupt_demo(tmp_path, sig)
    assert f"recording the session into {db}" in r.stderr
    assert r.returncode == status, r.stderr
    m = re.search(rf"{words}: (\d+) of (\d+) steps saved in (\S+)\nresume with: (.+)", r.stderr)
    assert m, r.stderr
    assert int(m.group(1)) == _saved(db) >= 10 and m.group(3) == db
    assert m.group(4) == f"robocal demo --resume --db {db}"
    assert "Traceback" not in r.stderr
    if sig == signal.SIGINT:                      # the printed command resumes and completes the session
        again = subprocess.run(_robocal(shlex.split(m.group(4))), capture_output=True, text=True, timeout=300,
                               cwd=tmp_path)
        assert again.returncode == 0, again.stderr
        total = m.group(2)
        assert f"{total}/{total} steps saved" in again.stderr
        assert f"report with: robocal reprocess {db} --report report/" in again.stderr


class FailingRunner(StillRunner):
    """Two steps: the first saved, then the rig fails (a device gone for good): the runner ends 'fail'."""

    def start(self):
        s = self.steps[0]
        self._emit("session", guid="f", path="f.db", resumed=False, done=0, total=2)
        self._emit("step_started", key=s.key, procedure=s.procedure, title=s.title, instruction=s.instruction,
                   index=0, total=2, attempt=1)
        self._emit("step_saved", key=s.key, status="accepted", attempts=1)
        self._emit("finished", exit_status="fail", error="DeviceTimeout: theodolite B: no reply after 3 tries")


def test_a_device_fault_that_stops_the_session_says_what_was_kept():
    def build(operator):
        steps = [Step(key=f"ruler/p0/{m}", procedure="ruler", title=f"mark {m}", instruction="Sight it.")
                 for m in "CD"]
        return SessionHandle(FailingRunner(operator, steps), lambda: None, "fault", "f.db", identities=[])

    async def main():
        app = RobocalApp(build, clock=False, final_results=False,
                         resume_command="robocal session --db f.db --theodolite A=geocom:/dev/ttyUSB0")
        async with app.run_test(size=(80, 24)) as pilot:
            for _ in range(60):
                await pilot.pause(0.05)
                if app.finished is not None:
                    break
            await pilot.pause(0.1)
            step = " ".join(str(app.query_one("#step").render()).split())
            assert "The session stopped: DeviceTimeout: theodolite B" in step
            assert "1 of 2 steps saved in f.db" in step
            assert "resume with: robocal session --db f.db --theodolite A=geocom:/dev/ttyUSB0" in step
            await pilot.press("q")

    asyncio.run(main())


@needs_tmux
def test_ctrl_c_in_the_tui_says_what_was_kept_and_the_command_resumes(tmp_path):
    db = tmp_path / "c.db"
    with Terminal(["session", "--emulate", "--db", str(db), "--only", "ruler/p0"], 80, 24) as t:
        t.wait_for("Do what the step says")
        t.keys("c")
        t.wait_for("checks passed")
        t.keys("a")
        t.wait_for("1/4 steps")
        t.keys("C-c")
        s = t.wait_for("resume with:")
    assert f"robocal session: interrupted: 1 of 4 steps saved in {db}\n" in s, s
    cmd = f"robocal session --db {db} --emulate --only ruler/p0"
    assert f"resume with: {cmd}\n" in s
    with Terminal(shlex.split(cmd)[1:], 80, 24) as t:                 # the command resumes at step 2
        s = t.wait_for("step 2 of 4")
        assert "1/4 steps" in s
        t.keys("q")
