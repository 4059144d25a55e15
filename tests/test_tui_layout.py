"""The TUI at the sizes operators have (80x24 laptop terminal, 120x40, 200x60): the step's title, instruction and
prompt always readable; side panels fold on small terminals and come back with a key; live readings labelled."""
import asyncio

import numpy as np

import pytest

from acq.session.steps import InputSpec, Step, TargetSpec
from app.tui.app import RobocalApp, SessionHandle
from app.tui.panels import Progress, joint_table, shorten, theodolite_lines
from tests.fakes.still_runner import StillRunner

TITLE = "Ruler placement 1: mark C"
INSTRUCTION = ("Ruler placement 1 (1.2 m in front, left), levelled in the plane of the theodolites. Sight mark C "
               "(0.0 mm from C) with theodolite A, then with B, face I then face II.")


def plan_steps() -> list[Step]:
    steps = [Step(key=f"ruler/p0/{m}", procedure="ruler", title=f"Ruler placement 1: mark {m}",
                  instruction=INSTRUCTION, targets=(TargetSpec(m),), encoders=False) for m in "CDE"]
    steps += [Step(key=f"compliance/j3/{i:02d}", procedure="compliance",
                   title=f"Joint 3 loading: {5 * i} kg at 500 mm on the lever of link 3",
                   instruction="Hang the weights.", inputs=(InputSpec("load_kg", "kg", "Mass hung", 5.0 * i),),
                   targets=(TargetSpec("A1"),)) for i in range(4)]
    return steps


def still_builder(operator):
    runner = StillRunner(operator, plan_steps())
    return SessionHandle(runner, lambda: None, "layout test", "layout.db", identities=[])


async def _at_first_step(app, pilot):
    for _ in range(100):
        await pilot.pause(0.05)
        if app.pending is not None and "theodolite A" in str(app.query_one("#live").render()):
            return
    raise AssertionError("the first step never showed")


async def _settled(pilot, tries: int = 30):
    """Wait until two screenshots 0.2 s apart agree: timers (live values, devices) have caught up with the events,
    so the snapshot shows the steady screen and not a moment in between."""
    last = None
    for _ in range(tries):
        await pilot.wait_for_scheduled_animations()
        await pilot.pause(0.2)
        shot = pilot.app.export_screenshot()
        if shot == last:
            return
        last = shot
    raise AssertionError("the screen never settled")


def _visible_text(app) -> str:
    return "\n".join(str(w.render()) for w in app.query("Static") if w.display and w.region.width > 0)


@pytest.mark.parametrize("size", [(80, 24), (120, 40), (200, 60)])
def test_step_title_instruction_and_prompt_get_the_room_they_need(size):
    async def main():
        app = RobocalApp(still_builder, clock=False, final_results=False)
        async with app.run_test(size=size) as pilot:
            await _at_first_step(app, pilot)
            step = app.query_one("#step")
            # the step panel spans most of the width: the title is not cut, the instruction wraps readably
            assert step.region.width >= min(size[0] - 2, 60), step.region
            assert TITLE in str(step.render())
            assert "Do what the step says" in str(app.query_one("#prompt").render())
            assert app.query_one("#prompt").region.height > 0          # the prompt is on screen
            live = str(app.query_one("#live").render())
            assert "theodolite A" in live and "J6" in live and "counts" in live and "deg" in live
            # empty panes are hidden until they have something
            assert not app.query_one("#plot").display
            assert not app.query_one("#checks").display
            side_shown = app.query_one("#right").display
            plan_shown = app.query_one("#plan").display
            if size[0] < 110:
                assert not side_shown and not plan_shown
            elif size[0] >= 160:
                assert side_shown and plan_shown
            # the folded panels come back with their key, and fold again
            await pilot.press("1")
            await pilot.pause(0.1)
            assert app.query_one("#plan").display is (not plan_shown)
            await pilot.press("1")
            await pilot.pause(0.1)
            assert app.query_one("#plan").display is plan_shown
            await pilot.press("2")
            await pilot.pause(0.1)
            assert app.query_one("#right").display is (not side_shown)
            # per-procedure progress and the step count in the header
            assert "0/7 steps" in app.sub_title and "ruler 0/3" in app.sub_title
            await pilot.press("q")

    asyncio.run(main())


@pytest.mark.parametrize("size", [(80, 24), (120, 40), (200, 60)])
def test_snapshot_first_step(snap_compare, size):
    async def run_before(pilot):
        await _at_first_step(pilot.app, pilot)
        await _settled(pilot)

    assert snap_compare(RobocalApp(still_builder, clock=False, final_results=False), run_before=run_before,
                        terminal_size=size)


def test_plan_labels_fit_and_full_title_on_highlight():
    async def main():
        app = RobocalApp(still_builder, clock=False, final_results=False)
        async with app.run_test(size=(200, 60)) as pilot:
            await _at_first_step(app, pilot)
            long_key = "compliance/j3/01"
            label = str(app.nodes[long_key].label)
            assert label.endswith("…") and len(label) <= app.PLAN_LABEL_CHARS + 2
            tree = app.query_one("#plan")
            app.nodes[long_key].parent.expand()
            await pilot.pause(0.1)
            tree.move_cursor(app.nodes[long_key])
            await pilot.pause(0.1)
            assert tree.border_subtitle == app.steps_by_key[long_key].title
            assert str(app.groups["ruler"].label) == "ruler  0/3"
            await pilot.press("q")

    asyncio.run(main())


def test_panels_are_labelled_and_fit_their_width():
    rows = joint_table((1, -2, 3, 4, 5, 6), [0.0, -1.5707963, 1.5707963, 0.0, 0.0, 0.0], width=40)
    assert all(len(r) <= 40 for r in rows)
    assert any("J1" in r for r in rows) and any("J6" in r for r in rows)
    assert "-90.000" in "\n".join(rows)
    lines = theodolite_lines({"B": {"hz_deg": 1.0, "v_deg": 2.0, "face": 2, "target": "P"},
                              "A": {"hz_deg": 3.0, "v_deg": 4.0, "face": 1, "target": "P"}})
    assert lines[0].startswith("theodolite A") and "face I " in lines[0] and "face II" in lines[1]
    assert shorten("abcdef", 4) == "abc…" and shorten("abc", 4) == "abc"


def test_time_estimate_counts_each_kind_of_step_at_its_own_pace():
    p = Progress.of(["ruler"] * 3 + ["sweep"] * 7)
    assert p.remaining_s() is None
    p.mark_done("ruler", 10.0)
    p.mark_done("ruler", 30.0)
    ruler_s = 10.0 + 0.3 * (30.0 - 10.0)                 # smoothed; the sweep, not timed yet, counts at its pace
    assert p.remaining_s() == pytest.approx(ruler_s * 8)
    assert p.header("sweep") == "2/10 steps · sweep 0/7 · about 2 min left"
    p.mark_done("ruler", 16.0)
    p.mark_done("sweep", 100.0)
    assert p.remaining_s() == pytest.approx(100.0 * 6)   # six sweeps left at the sweep's own pace
    p.mark_done("nothing")                      # an unknown procedure changes nothing
    assert p.steps_done == 4


def test_time_estimate_is_steady_when_kinds_of_step_alternate():
    """Quick encoder windows and slow loads in turn (what made the estimate jump 110 -> 50 -> 80 -> 42 min): the time
    left, read after every step, never jumps by more than a quarter once a few steps were timed, and ends near the
    truth."""
    kinds = ["coupling", "compliance"] * 40
    pace = {"coupling": 20.0, "compliance": 200.0}
    p = Progress.of(kinds)
    now, shown = 0.0, []
    rng = np.random.default_rng(1)
    for k in kinds:
        took = pace[k] * rng.uniform(0.7, 1.3)
        now += took
        p.mark_done(k, took, now_s=now)
        left = p.remaining_s(now)
        if left is not None:
            shown.append(left)
    truth_at_10 = sum(pace[k] for k in kinds[10:])
    assert abs(shown[8] - truth_at_10) / truth_at_10 < 0.2
    steps = [abs(b - a) / a for a, b in zip(shown[6:-10], shown[7:-9])]
    assert max(steps) < 0.25, max(steps)


def test_time_left_reads_with_its_unit():
    from app.tui.panels import duration_text
    assert duration_text(42) == "40 s" and duration_text(14 * 60 + 10) == "14 min"
    assert duration_text(112 * 60) == "1 h 50 min" and duration_text(47 * 60) == "45 min"
