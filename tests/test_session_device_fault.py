"""An unplugged theodolite fails the step attempt, not the session: the operator repeats once it is back."""
from sim.emulate import registry
from app.demo import build_demo
from acq.session.headless import ScriptedOperator


def test_unplugged_theodolite_mid_session_is_survived(tmp_path):
    db = tmp_path / "f.db"
    unplugged = {}

    class Operator(ScriptedOperator):
        def ask(self, req):
            # unplug theodolite A while the operator prepares the second ruler step; plug it back at the fault
            if req.kind == "setup" and req.step.key.endswith("/D") and not unplugged:
                registry.unplug(self.demo.names[0])                    # the cable comes out
                unplugged["done"] = True
            if req.kind == "decision" and any(c.name == "device" for c in req.checks):
                unplugged["fault"] = [c.message for c in req.checks]
                registry.replug(self.demo.names[0])                    # ... and goes back in
            return super().ask(req)

    op = Operator()
    demo = build_demo(db, seed=2, operator=op, steps_filter=lambda s: s.key.startswith("ruler/p0"))
    op.demo = demo
    try:
        state = demo.runner.run()
    finally:
        demo.close()
    assert state == "finished"
    assert "fault" in unplugged and "theodolite A" in unplugged["fault"][0] and "repeat" in unplugged["fault"][0]
    from acq.session.store import SessionStore
    store = SessionStore.open(str(db))
    from acq.session.setup import standard_setup
    marks = standard_setup()["ruler"]["placements"][0]["marks"]          # the first placement's marks
    assert sorted(store.done_keys()) == sorted(f"ruler/p0/{m}" for m in marks)
    store.close()
