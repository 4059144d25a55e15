"""The runner's side of entry (issue 26, item 1): a measured value the step needs is never taken from the plan -- a
step whose value was not entered acquires nothing and offers nothing to accept -- and a value far from the plan's is
a failed check naming both.  Driven on the emulated cell with an operator that answers like a person would."""
import sqlite3

from app.demo import build_demo
from acq.session.runner import Answer

KEY = "compliance/j3/01"


class Operator:
    """Enters nothing at the first set-up, then 5 kg where the plan hangs about 1 kg; accepts what it is shown."""

    def __init__(self):
        self.decisions = []

    def ask(self, req):
        if req.kind == "setup":
            if req.attempt == 1:
                return Answer("continue", {})
            return Answer("continue", {"load_kg": 5.0, "lever_mm": 500.0, "theta_i_deg": 0.0})
        self.decisions.append(req)
        if "accept" not in req.choices:
            return Answer("repeat")
        return Answer("accept", note="5 kg hung on purpose")


def test_a_value_not_entered_is_refused_and_one_far_from_the_plan_fails_naming_both(tmp_path):
    db = tmp_path / "e.db"
    op = Operator()
    d = build_demo(db, seed=0, plan={"procedures": ["compliance"], "compliance": {"joints": [3]}, "seed": 0},
                   steps_filter=lambda s: s.key == KEY, operator=op)
    try:
        assert d.runner.run() == "finished"
    finally:
        d.close()
    first, second = op.decisions
    # nothing entered: one failed check per value, the field named, nothing to accept
    assert "accept" not in first.choices
    names = {c.name for c in first.checks}
    assert names == {"entered load_kg", "entered lever_mm", "entered theta_i_deg"}
    msg = next(c.message for c in first.checks if c.name == "entered load_kg")
    assert "Mass now on the lever of joint 3 (kg) was not entered" in msg and "1.0197 kg" in msg
    # 5 kg where the plan hangs 1.0197 kg: a failed check that names both; the lever and angle as planned pass
    plan = {c.name: c for c in second.checks if c.name.startswith("as planned")}
    assert not plan["as planned load_kg"].passed
    assert "entered 5 kg" in plan["as planned load_kg"].message and "the plan 1.0197 kg" in plan["as planned load_kg"].message
    assert plan["as planned lever_mm"].passed and plan["as planned theta_i_deg"].passed
    with sqlite3.connect(db) as c:
        attempts = {a for (a,) in c.execute("SELECT DISTINCT r.attempt FROM reading r JOIN step s USING (step_id) "
                                            "WHERE s.key = ?", (KEY,))}
        entered = c.execute("SELECT i.value FROM operator_input i JOIN step s USING (step_id) WHERE s.key = ? AND "
                            "i.name = 'load_kg'", (KEY,)).fetchall()
    assert attempts == {2}                      # the attempt without its values acquired nothing
    assert entered == [(5.0,)]                  # the value the reduction uses is the one entered


def test_the_scripted_demo_operator_enters_what_its_bench_hung(tmp_path):
    """The headless operator reads the load, lever and angle off the emulated bench (never the plan's hint): every
    compliance step's entries pass the as-planned check, and the stored load is the mass the bench hung."""
    db = tmp_path / "s.db"
    d = build_demo(db, seed=0, plan={"procedures": ["compliance"], "compliance": {"joints": [3]}, "seed": 0},
                   steps_filter=lambda s: s.key.startswith("compliance/j3/0"))
    hung = {s.key: s.setup["loads"][0]["mass_kg"] for s in d.runner.steps}
    try:
        assert d.runner.run() == "finished"
    finally:
        d.close()
    with sqlite3.connect(db) as c:
        rows = c.execute("SELECT r.name, r.passed FROM check_result r WHERE r.name LIKE 'as planned%' OR "
                         "r.name LIKE 'entered%'").fetchall()
        loads = dict(c.execute("SELECT s.key, i.value FROM operator_input i JOIN step s USING (step_id) WHERE "
                               "i.name = 'load_kg'").fetchall())
    assert rows and all(p for _, p in rows) and not any(n.startswith("entered") for n, _ in rows)
    assert loads == hung
