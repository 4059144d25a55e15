"""The Textual TUI, driven as an operator would: Pilot flows on the emulated instruments, snapshots, and a real
terminal under tmux."""
import asyncio
import os
import re
import subprocess
import sys
import time

import pytest

from app.commands.session import emulated_builder
from acq.session.store import SessionStore
from app.tui.app import RobocalApp
from tests.tmux_term import Terminal, needs_tmux


def answer_all(app, pilot, until, press_first=2, timeout=90.0):
    """Answer the runner's prompts: the first ``press_first`` by real key presses, the rest by the same actions."""
    async def go():
        t0 = time.monotonic()
        n = 0
        while time.monotonic() - t0 < timeout:
            await pilot.pause(0.05)
            if until(app):
                return n
            p = app.pending
            if p is not None and not p.future.done():
                key = "c" if p.request.kind == "setup" else "a"
                if n < press_first:
                    await pilot.press(key)
                else:
                    app.action_answer({"c": "continue", "a": "accept"}[key])
                n += 1
        raise AssertionError(f"timed out in state {app.state}")
    return go()


def run(coro):
    return asyncio.run(coro)


def _ruler_steps(placement: int | None = None) -> int:
    """Ruler steps of the standard set-up (every placement's sighted marks), or of one placement."""
    from acq.session.setup import standard_setup
    pls = standard_setup()["ruler"]["placements"]
    return sum(len(p["marks"]) for p in (pls if placement is None else [pls[placement]]))


def test_ruler_and_one_joint_sweep_end_to_end(tmp_path):
    db = tmp_path / "s.db"

    async def main():
        app = RobocalApp(emulated_builder(str(db), 0, ["ruler", "sweep/j2/"]), clock=False)
        async with app.run_test(size=(180, 50)) as pilot:
            n = await answer_all(app, pilot, lambda a: a.finished is not None)
            assert app.finished["exit_status"] == "success", app.finished
            saved = [k for k, d in app.data.items() if d.status == "accepted"]
            assert len(saved) == _ruler_steps() + 5 and n >= 2 * len(saved)       # ruler + 5 sweep positions
            # the plan shows every step done, the sweep's plot has data, the live panel shows angles and counts
            assert all(str(app.nodes[k].label)[0] in "✔⚠" for k in saved)     # accepted (⚠: a check failed)
            live = str(app.query_one("#live").render())
            assert "theodolite A" in live and "counts" in live
            assert app.plotted is not None and app.plotted[0] == "circle fit residuals" and app.plotted[1] >= 8
            # at the end: the session is reprocessed, the report written and the estimates listed with errors
            t0 = time.monotonic()
            while app.results_dir is None and time.monotonic() - t0 < 60:
                await pilot.pause(0.2)
            assert app.results_dir is not None
            assert (tmp_path / "s_report" / "report.html").exists()
            step = str(app.query_one("#step").render())
            assert "report.html" in step
            assert app.table_columns[:3] == ["estimate", "value ± 1σ", "unit"]
            names = [str(r[0]) for r in app.table_rows]
            assert "theodolite baseline L" in names and not any("_mm" in n or "ruler." in n for n in names), names
            await pilot.press("q")

    run(main())
    store = SessionStore.open(str(db), read_only=True) if "read_only" in SessionStore.open.__code__.co_varnames \
        else SessionStore.open(str(db))
    keys = store.done_keys()
    assert {k for k in keys if k.startswith("ruler")} and {k for k in keys if k.startswith("sweep/j2/")}
    store.close()


def test_repeat_skip_and_pause_then_resume(tmp_path):
    db = tmp_path / "p.db"

    async def first():
        app = RobocalApp(emulated_builder(str(db), 1, ["ruler"]), clock=False)
        async with app.run_test(size=(180, 50)) as pilot:
            await answer_all(app, pilot, lambda a: a.pending is not None and a.pending.request.kind == "decision",
                             press_first=0)
            await pilot.press("r")                                   # repeat the first step
            await answer_all(app, pilot, lambda a: a.pending is not None and a.pending.request.kind == "decision"
                             and a.pending.request.attempt == 2, press_first=0)
            app.action_answer("accept")
            await answer_all(app, pilot, lambda a: a.pending is not None and a.pending.request.kind == "setup",
                             press_first=0)
            await pilot.press("s")                                   # skip the second step
            await answer_all(app, pilot, lambda a: a.pending is not None and a.pending.request.kind == "setup",
                             press_first=0)
            await pilot.press("p")                                   # pause at the third
            await answer_all(app, pilot, lambda a: a.finished is not None, press_first=0)
            assert app.finished["exit_status"] == "paused"
            statuses = {k: d.status for k, d in app.data.items() if d.status}
            assert list(statuses.values())[:2] == ["accepted", "skipped"]
            await pilot.press("q")
            return statuses

    done_first = run(first())

    async def second():
        app = RobocalApp(emulated_builder(str(db), 1, ["ruler"]), clock=False)
        async with app.run_test(size=(180, 50)) as pilot:
            await answer_all(app, pilot, lambda a: a.finished is not None, press_first=0)
            assert app.finished["exit_status"] == "success"
            # the two saved steps were not asked again
            assert not (set(done_first) & {k for k, d in app.data.items() if d.status})
            await pilot.press("q")

    run(second())


def test_operator_input_must_be_a_number(tmp_path):
    db = tmp_path / "c.db"

    async def main():
        app = RobocalApp(emulated_builder(str(db), 0, ["compliance/j3/00"]), clock=False)
        async with app.run_test(size=(180, 50)) as pilot:
            await answer_all(app, pilot, lambda a: a.pending is not None and a.pending.request.kind == "setup"
                             and a.pending.request.step.inputs, press_first=0)
            specs = app.pending.request.step.inputs
            spec = specs[0]
            for _ in range(60):                                                 # the first field gets the keys
                await pilot.pause(0.05)
                if app.query(f"#in-{spec.name}") and app.focused is app.query_one(f"#in-{spec.name}"):
                    break
            box = app.query_one(f"#in-{spec.name}")
            assert box.value == "" and str(spec.suggested) in box.placeholder or f"{spec.suggested:g}" in box.placeholder
            box.value = "ten"
            app.action_answer("continue")
            assert app.pending is not None and not app.pending.future.done()     # refused, still waiting
            box.value = "44.5"
            app.action_answer("continue")                                       # the lever is not entered yet
            assert app.pending is not None and not app.pending.future.done()
            lever = app.query_one(f"#in-{specs[1].name}")
            for _ in range(40):
                await pilot.pause(0.05)
                if app.focused is lever:
                    break
            assert app.focused is lever                                         # the missing field has the keys
            for other in specs[1:]:
                app.query_one(f"#in-{other.name}").value = f"{other.suggested:g}"
            app.action_answer("continue")
            await answer_all(app, pilot, lambda a: a.finished is not None, press_first=0)
            assert app.data[app.current_key].inputs[spec.name] == 44.5
            await pilot.press("q")

    run(main())


def test_a_device_that_cannot_be_opened_is_a_message_not_a_traceback():
    def broken(operator):
        raise ConnectionError("theodolite A: /dev/ttyUSB0: no such device")

    async def main():
        app = RobocalApp(broken, clock=False)
        async with app.run_test(size=(120, 40)) as pilot:
            await pilot.pause(0.3)
            text = str(app.query_one("#step").render())
            assert "Cannot start the session" in text and "ttyUSB0" in text
            await pilot.press("q")

    run(main())


def test_snapshot_help_screen(snap_compare):
    def never(operator):
        raise ConnectionError("not connected in this snapshot")

    async def run_before(pilot):
        await pilot.pause(0.3)
        await pilot.press("question_mark")
        await pilot.pause(0.2)

    assert snap_compare(RobocalApp(never, clock=False), run_before=run_before, terminal_size=(120, 40))


def test_snapshot_cannot_start(snap_compare):
    def never(operator):
        raise ConnectionError("encoder tap: can0: network is down")

    async def run_before(pilot):
        await pilot.pause(0.3)

    assert snap_compare(RobocalApp(never, clock=False), run_before=run_before, terminal_size=(120, 40))


@needs_tmux
def test_real_terminal_under_tmux(tmp_path):
    """The operator's laptop terminal (80x24): every prompt readable and answered by key presses; once two steps were
    timed the header gives the time left with its unit."""
    db = tmp_path / "t.db"
    seen_step = seen_left = False
    with Terminal(["session", "--emulate", "--db", str(db), "--only", "ruler/p0"], 80, 24) as t:
        t0 = time.monotonic()
        while time.monotonic() - t0 < 60:
            time.sleep(0.5)
            s = t.screen()
            seen_step |= "Ruler placement" in s
            seen_left |= bool(re.search(r"about \d+ (s|min) left", s.splitlines()[0] if s else ""))
            if "Press q to quit" in s:
                break
            if "Do what the step says" in s:
                t.keys("c", pause_s=0)
            elif "checks passed" in s or "check(s) failed" in s:
                t.keys("a", pause_s=0)
        s = t.screen()
        assert seen_step, s
        assert "Press q to quit" in s and "success" in s, s
        assert seen_left
        t.keys("q", pause_s=1.0)
    assert db.exists()


def test_interface_stays_responsive_under_a_flood_and_keeps_every_record():
    """A bus at its limit (8 kHz live updates) and 200 readings per step: prompts and records all arrive, keys work.
    The k-th question waits for k x 300 tap updates (an event count, not a time), so the flood runs while the keys
    are pressed on any machine; how fast a key is answered is measured in ``benchmarks/bench_tui_keys.py``."""
    from app.tui.app import SessionHandle
    from tests.fakes.fake_runner import FakeRunner

    holder = {}

    def build(operator):
        r = FakeRunner(operator, n_steps=5, readings_per_step=200, rate_hz=8000.0, updates_per_step=300)
        holder["runner"] = r
        return SessionHandle(r, lambda: None, "flood", "", identities=[])

    async def main():
        app = RobocalApp(build, clock=False)
        async with app.run_test(size=(160, 45)) as pilot:
            t0 = time.monotonic()
            while app.finished is None and time.monotonic() - t0 < 120:      # a guard against a hang, not a bound
                await pilot.pause(0.05)
                if app.pending is not None and not app.pending.future.done():
                    await pilot.press("a")
            runner = holder["runner"]
            assert app.finished == {"exit_status": "success", "error": None}
            assert runner.asked == 5
            assert sum(len(d.readings) for d in app.data.values()) == 5 * 200      # no record dropped
            assert sum(d.status == "accepted" for d in app.data.values()) == 5
            assert runner.rig.tap.updates >= 5 * 300                               # the flood really ran
            live = str(app.query_one("#live").render())
            assert "counts" in live                                                # coalesced latest value shown
            await pilot.press("q")

    run(main())


def test_devices_by_url_through_the_same_drivers(tmp_path):
    """The non-emulated path: theodolites and tap named by URL (here emulator URLs and a virtual CAN bus), a set-up
    file from the template, and the ruler steps recorded through the TUI."""
    import can

    from app.commands.session import real_builder, setup_template
    from sim.emulate.can_node import CanTapNode
    from sim.emulate.tap_device import TapModel
    from sim.emulate.factories import demo_world
    from calib.loading import load_robot
    import json as _json

    setup = tmp_path / "setup.json"
    setup.write_text(_json.dumps(setup_template()))
    channel = f"tui-url-{os.getpid()}"
    world = demo_world(seed=3)
    node = CanTapNode(can.Bus(interface="virtual", channel=channel), TapModel(world, load_robot(), rate_hz=200.0),
                      own_bus=True).start()
    db = tmp_path / "u.db"
    build = real_builder(str(db), ["A=geocom:robocal://geocom?seed=3&station=A",
                                   "B=gsi:robocal://gsi?seed=3&station=B"], f"can:virtual:{channel}", str(setup),
                         None, None, ["ruler/p0"])

    async def main():
        app = RobocalApp(build, clock=False)
        async with app.run_test(size=(180, 50)) as pilot:
            await answer_all(app, pilot, lambda a: a.finished is not None, press_first=0)
            assert app.finished["exit_status"] == "success", app.finished
            devices = str(app.query_one("#devices").render())
            assert "geocom" in devices and "gsi" in devices and "encoder tap" in devices
            await pilot.press("q")

    try:
        run(main())
    finally:
        node.stop()
    from acq.session.store import SessionStore
    store = SessionStore.open(str(db))
    assert len([k for k in store.done_keys() if k.startswith("ruler/p0")]) == _ruler_steps(placement=0)
    store.close()


@pytest.mark.parametrize("args,words", [
    (["session"], "give --emulate, or the devices"),
    (["session", "--theodolite", "A:geocom", "--theodolite", "B=geocom:x"], "expected NAME=KIND:URL"),
    (["session", "--theodolite", "A=geocom:x", "--theodolite", "B=geocom:y", "--tap", "can:vcan0"],
     "expected can:INTERFACE:CHANNEL"),
    (["session", "--theodolite", "A=geocom:x", "--theodolite", "B=geocom:y"], "needs --setup"),
])
def test_session_command_bad_device_arguments(tmp_path, args, words):
    r = subprocess.run([sys.executable, "-m", "app.cli", *args, "--db", str(tmp_path / "n.db")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr


def test_a_plan_that_fails_the_preflight_is_refused_with_the_reason(tmp_path):
    """A session whose plan drives joint 4 past its stop: the TUI shows why, nothing is recorded."""
    from app.demo import build_demo, demo_plan
    from sim.twin import Twin
    db = tmp_path / "bad.db"
    plan = demo_plan(Twin(seed=2), 2, n_poses=8)
    plan["procedures"] = ["transmission"]
    plan["transmission"] = {"joints": [4], "points": 3, "range_deg": {"4": [-150.0, 0.0]}}
    build_demo(db, seed=2, plan=plan).close()

    async def main():
        app = RobocalApp(emulated_builder(str(db), 2), clock=False)
        async with app.run_test(size=(180, 50)) as pilot:
            t0 = time.monotonic()
            while app.finished is None and time.monotonic() - t0 < 30:
                await pilot.pause(0.1)
            assert app.finished["exit_status"] == "refused"
            step = str(app.query_one("#step").render())
            assert "pre-flight failed for 1 step(s)" in step and "te/j4/00: joint limit" in step
            assert "Nothing was recorded" in step and "powered" not in step
            await pilot.press("q")

    run(main())
    store = SessionStore.open(str(db))
    assert not store.done_keys()
    assert store.session_row()["exit_status"] is None
    store.close()
