"""The TUI in a real terminal (tmux) at the operator's laptop size, 80x24, and at 160x48 (issue 26, item 2): the
footer keeps every key (help and quit included), the step's title, instruction and prompt and the live readings are
on screen, a failed check's reason is shown whole, wrapped, the time left carries its unit, and the log holds what
the operator acts on, not state changes.  Values are typed as an operator types them (item 1)."""
import pytest

from tests.tmux_term import Terminal, needs_tmux, panel_text

SIZES = [(80, 24), (160, 48)]
FOOTER_SETUP = ("c continue", "s skip", "p pause", "x abort", "? help", "q quit")
FOOTER_DECISION = ("a accept", "r repeat", "s skip", "p pause", "x abort", "? help", "q quit")


@needs_tmux
@pytest.mark.parametrize("size", SIZES)
def test_a_load_step_fits_the_terminal_and_a_wrong_mass_is_shown_whole(tmp_path, size):
    db = tmp_path / "t.db"
    with Terminal(["session", "--emulate", "--db", str(db), "--only", "compliance/j3/01"], *size) as t:
        s = t.wait_for("type each value you measured", "counts")
        lines = s.splitlines()
        assert len(lines) <= size[1] and "robocal" in lines[0]
        footer = lines[-1]
        assert all(k in footer for k in FOOTER_SETUP), footer
        step = panel_text(s, "Joint 3 loading")
        assert "Joint 3 loading: 1.02 kg" in step and "then sight A1 and A2 with theodolite A, then with B." in step
        assert "plan 1.0197 kg" in s                                   # the plan's value, as a hint
        for line in ("joint", "deg", "counts", "J6"):                 # the encoders live (nothing sighted yet)
            assert line in s, (line, s)
        # typed as an operator does: the mass (5 kg, not the planned 1.02), Enter, Tab to the next empty field
        t.keys("5", "Enter", "Tab", "5", "0", "0", "Enter", "Tab", "0", "Enter", "c")
        s = t.wait_for("check(s) failed", "FAIL")
        footer = s.splitlines()[-1]
        assert all(k in footer for k in FOOTER_DECISION), footer
        reason = panel_text(s, "FAIL")
        assert ("entered 5 kg, the plan 1.0197 kg" in reason
                and "the entered value is the one used" in reason), reason      # whole, wrapped, not cut
        for line in ("theodolite A", "theodolite B", "point A1", "counts"):  # the readings still on screen
            assert line in s, (line, s)
        if size[0] >= 160:                 # the log beside the step: the failed check, no state changes or saves
            log = panel_text(s, "FAILED")
            assert "as planned load_kg FAILED" in log and " -> " not in log and "saved compliance" not in log
        t.keys("x")
        t.wait_for("Abort the session?")
        t.keys("y")
        s = t.wait_for("Press q to quit")
        assert "Aborted." in s and "0 of 1 steps saved in" in panel_text(s, "Aborted.")
        assert "resume with: robocal session --db" in panel_text(s, "Aborted.")
        t.keys("q")
