"""Entry never traps the operator (issue 26, item 1): in a value field the step's keys still act and stay in the
footer, Enter takes the value and hands the keys back, Escape puts the field back, Tab reaches the first field
whatever the width, a measured value is never pre-filled with the plan, and ``x`` asks before it aborts."""
import asyncio

import pytest

from acq.session.steps import InputSpec, Step, TargetSpec
from app.tui.app import RobocalApp, SessionHandle
from tests.fakes.still_runner import StillRunner

LOAD = InputSpec("load_kg", "kg", "Mass hung", 1.02, tolerance=0.1)
GAUGE = InputSpec("gauge1_mm", "mm", "Dial gauge 1 at 300 mm")
SIZES = [(80, 24), (200, 60)]


def _builder(holder):
    def build(operator):
        step = Step(key="compliance/j3/01", procedure="compliance", title="Joint 3 loading: 1.02 kg",
                    instruction="Hang 1.02 kg on the lever, read the gauge.", inputs=(LOAD, GAUGE),
                    targets=(TargetSpec("A1"),))
        holder["runner"] = StillRunner(operator, [step])
        return SessionHandle(holder["runner"], lambda: None, "entry test", "entry.db", identities=[])
    return build


async def _at_prompt(app, pilot):
    for _ in range(100):
        await pilot.pause(0.05)
        if app.pending is not None and app.query(f"#in-{LOAD.name}") and \
                app.focused is app.query_one(f"#in-{LOAD.name}"):          # the first field has the keys
            return
    raise AssertionError("the set-up prompt never showed")


def _drive(size, scenario) -> None:
    """Run ``scenario(app, pilot, runner)`` at the first set-up prompt of a step with two values, then quit."""
    holder = {}

    async def main():
        app = RobocalApp(_builder(holder), clock=False, final_results=False)
        async with app.run_test(size=size) as pilot:
            await _at_prompt(app, pilot)
            await scenario(app, pilot, holder["runner"])
            await pilot.press("q")

    asyncio.run(main())


async def _answered(pilot, runner) -> None:
    for _ in range(40):
        await pilot.pause(0.05)
        if runner.answers:
            return


def _shown_keys(app) -> set[str]:
    return {b.binding.key for b in app.active_bindings.values() if b.binding.show and b.enabled}


@pytest.mark.parametrize("size", SIZES)
def test_step_keys_act_and_stay_shown_while_a_field_has_focus(size):
    async def scenario(app, pilot, runner):
        load, gauge = app.query_one("#in-load_kg"), app.query_one("#in-gauge1_mm")
        # never pre-filled: the plan's value is the hint beside an empty field
        assert load.value == "" and "plan 1.02 kg" in load.placeholder
        assert app.focused is load
        assert {"c", "s", "p", "x", "question_mark", "q"} <= _shown_keys(app)       # the footer keeps them
        await pilot.press("2", "5", "c")                 # 'c' is the step's: not typed into the field
        await pilot.pause(0.1)
        assert load.value == "25"
        # ... and continuing is refused, naming the field not entered; that field gets the keys
        assert not runner.answers and app.pending is not None
        assert app.focused is gauge
        assert any("Dial gauge 1 at 300 mm (mm): not entered" in str(n.message) for n in app._notifications)
        await pilot.press("0", ".", "1", "2", "enter")   # Enter takes it and hands the keys back
        await pilot.pause(0.1)
        assert app.focused is None and gauge.value == "0.12"
        await pilot.press("tab")                         # Tab: the first field (none is empty now)
        await pilot.pause(0.1)
        assert app.focused is load
        await pilot.press("9", "escape")                 # Escape: the field as it was, keys back to the step
        await pilot.pause(0.1)
        assert load.value == "25" and app.focused is None
        await pilot.press("c")
        await _answered(pilot, runner)
        ans = runner.answers[0]
        assert ans.action == "continue" and ans.values == {"load_kg": 25.0, "gauge1_mm": 0.12}

    _drive(size, scenario)


@pytest.mark.parametrize("size", SIZES)
def test_tab_reaches_the_first_empty_field_at_every_width(size):
    async def scenario(app, pilot, runner):
        await pilot.press("3", "enter")
        await pilot.pause(0.1)
        assert app.focused is None
        await pilot.press("tab")
        await pilot.pause(0.1)
        assert app.focused is app.query_one("#in-gauge1_mm")       # the plan tree never comes first
        await pilot.press("tab")
        await pilot.pause(0.1)
        assert app.focused is app.query_one("#in-load_kg")

    _drive(size, scenario)


def test_x_asks_before_it_aborts():
    async def scenario(app, pilot, runner):
        await pilot.press("x")
        await pilot.pause(0.2)
        assert type(app.screen).__name__ == "ConfirmAbort"
        await pilot.press("c")                           # other keys do nothing while it asks
        await pilot.press("n")
        await pilot.pause(0.2)
        assert type(app.screen).__name__ != "ConfirmAbort" and not runner.answers
        await pilot.press("x", "y")
        await _answered(pilot, runner)
        assert [a.action for a in runner.answers] == ["abort"]

    _drive((80, 24), scenario)


@pytest.mark.parametrize("size", SIZES)
def test_a_number_typed_with_no_field_focused_starts_the_first_empty_field(size):
    """An operator typing the moment the step appears, before the first field holds the keys: the digits land in the
    first empty field, none is lost or taken as a step's key."""
    async def scenario(app, pilot, runner):
        app.set_focus(None)
        await pilot.pause(0.05)
        await pilot.press("2", "5", "enter")
        assert app.query_one(f"#in-{LOAD.name}").value == "25"
        assert app.query_one(f"#in-{GAUGE.name}").value == ""
        assert not runner.answers                       # nothing continued
    _drive(size, scenario)
