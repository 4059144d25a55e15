"""The reduction while the session records (offline.reduction.live, app.live_reduction): the stages run as their
procedures complete, and the results are the offline reduction's, number for number -- on the shipped demo session
read as it stood after each step, in-process and through the worker process; every stage declares the procedures
whose steps it reads (else it would run before they are recorded); the recorder's bookkeeping of complete
procedures; a failing worker is one line, never a wrong result."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from acq.session.steps import Step
from app.live_reduction import CompletedProcedures, ReductionWorker, WorkerFailed
from app.reprocess import reprocess
from offline.reduction import run as run_module
from offline.reduction.context import Reduction
from offline.reduction.live import LiveReduction
from offline.reduction.run import reduce_session
from offline.reduction.session import load_session
from offline.reduction.stages import all_stages

ROOT = Path(__file__).resolve().parents[1]
SESSION = ROOT / "examples" / "demo-session.db"
TIMING = ("elapsed_s", "reprocessed_unix_s")


def _equal(a, b, where: str = "") -> list[str]:
    """Where two results documents differ (provenance timing aside): exact, arrays and NaN included."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{where}: keys {sorted(set(a) ^ set(b))}"]
        return [d for k in a if not (where == "/provenance" and k in TIMING) for d in _equal(a[k], b[k], f"{where}/{k}")]
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            return [f"{where}: {len(a)} against {len(b)} items"]
        return [d for i, (u, v) in enumerate(zip(a, b)) for d in _equal(u, v, f"{where}[{i}]")]
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return [] if np.array_equal(a, b, equal_nan=True) else [f"{where}: arrays differ"]
    if isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b):
        return []
    return [] if a == b and type(a) is type(b) else [f"{where}: {a!r} against {b!r}"]


@pytest.fixture(scope="module")
def session(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("live") / "demo-session.db"
    shutil.copyfile(SESSION, path)
    return str(path)


def _as_it_stood(path: str, n: int):
    """The session's reader as the database stood after its first ``n`` accepted steps."""
    def read(p, procedures=None, skip=()):
        data = load_session(p)
        data.steps = [s for s in data.steps[:n] if (procedures is None or s["procedure"] in procedures)
                      and s["procedure"] not in skip]
        return data
    return read


def test_stages_run_as_procedures_complete_and_give_the_offline_results(session):
    order = [s["procedure"] for s in load_session(session).steps]
    handed: list[tuple] = []
    live = LiveReduction(session, planned=list(dict.fromkeys(order)),
                         on_output=lambda name, value, problems: handed.append(
                             (name, value, "accuracy" in live.ctx.figs)))
    ran_before_the_end: list[str] = []
    for i, proc in enumerate(order):
        if proc not in order[i + 1:]:                   # its last step: the procedure is complete
            live.read = _as_it_stood(session, i + 1)
            ran_before_the_end += live.complete([proc])
    assert "poses" in ran_before_the_end and "ruler" in ran_before_the_end      # reduced while recording
    model, _ = live.output("identified")
    live.read = load_session
    got = live.finish()
    want = reduce_session(session)
    assert _equal(got, want) == []
    assert model == want["robot"]
    names = [h[0] for h in handed]
    assert sorted(names) == sorted({"stations", "axes", "compliance", "transmission", "identified", "iso9283"})
    assert len(names) == len(set(names))               # each output handed on once
    identified = next(h for h in handed if h[0] == "identified")
    assert identified[1] == want["robot"] and not identified[2]    # the model before the held-out accuracy


def test_an_output_not_reduced_yet_is_a_key_error(session):
    live = LiveReduction(session, planned=["ruler", "poses"])
    live.complete(["ruler"])
    with pytest.raises(KeyError, match="identified"):
        live.output("identified")


def test_every_stage_declares_the_procedures_it_reads(session, monkeypatch):
    asked: dict[str, set] = {}
    current: list[str] = []
    steps_of, run_stage = Reduction.steps_of, run_module.run_stage

    def spy_steps_of(self, procedures):
        asked.setdefault(current[-1], set()).update(procedures)
        return steps_of(self, procedures)

    def spy_run_stage(ctx, stage):
        current.append(stage.name)
        run_stage(ctx, stage)

    monkeypatch.setattr(Reduction, "steps_of", spy_steps_of)
    monkeypatch.setattr(run_module, "run_stage", spy_run_stage)
    run_module.reduce_session(session)
    for stage in all_stages():
        undeclared = asked.get(stage.name, set()) - set(stage.procedures) - set(stage.reads)
        assert not undeclared, f"stage {stage.name} reads the steps of {undeclared} without declaring them"
    assert asked["poses"] >= {"coupling"}          # the check can fail: the pose set reads the wrist coupling


def _steps(*keys_procs) -> list[Step]:
    return [Step(key=k, procedure=p, title=k, instruction="") for k, p in keys_procs]


def test_completed_procedures_from_the_runners_events():
    steps = _steps(("r1", "ruler"), ("r2", "ruler"), ("p1", "poses"), ("i1", "iso9283"), ("p2", "poses"))
    t = CompletedProcedures(steps)
    assert t.complete == [] and t.planned == ["ruler", "poses", "iso9283"]
    assert t.saved("r1") == [] and t.saved("r2") == ["ruler"]
    assert t.saved("r2") == []                         # saved twice: said once
    assert t.saved("p1") == [] and t.saved("i1") == ["iso9283"] and t.saved("p2") == ["poses"]
    assert t.saved("unknown") == []
    resumed = CompletedProcedures(steps, saved_keys=["r1", "r2", "p1"])
    assert resumed.complete == ["ruler"] and resumed.saved("p2") == ["poses"]


def test_the_worker_process_gives_what_reprocess_gives(session):
    worker = ReductionWorker.spawn()
    try:
        steps = [Step(key=s["key"], procedure=s["procedure"], title="", instruction="") for s in load_session(session).steps]
        worker.open(session, CompletedProcedures(steps, saved_keys=[s.key for s in steps]), wanted=("identified",))
        model, problems = worker.output("identified")
        got = worker.finish()
    finally:
        worker.close()
    want = reprocess(session)
    assert _equal(got, want) == []
    assert _untrue(model) == _untrue(want["robot"]) and isinstance(problems, list)


def _untrue(model: dict) -> dict:
    """A model document without the twin's truths (an emulated session's results are scored after the reduction)."""
    scored = ("truth", "truth_raw", "note")
    return {**model, "parameters": [{k: v for k, v in p.items() if k not in scored} for p in model["parameters"]]}


def test_an_output_sent_that_nobody_reads_is_passed_over(session):
    worker = ReductionWorker.spawn()
    try:
        steps = [Step(key=s["key"], procedure=s["procedure"], title="", instruction="")
                 for s in load_session(session).steps]
        worker.open(session, CompletedProcedures(steps, saved_keys=[s.key for s in steps]), wanted=("identified",))
        got = worker.finish()                           # no compensated run: the model sent is not read
    finally:
        worker.close()
    assert got["session"]["steps_accepted"] == len(steps) and got["robot"] is not None


def test_an_output_that_cannot_be_made_yet_is_a_failure_not_a_wait(session):
    worker = ReductionWorker.spawn()
    try:
        steps = [Step(key=s["key"], procedure=s["procedure"], title="", instruction="")
                 for s in load_session(session).steps]
        not_coupling = [s.key for s in steps if s.procedure != "coupling"]   # the pose set reads the coupling steps
        worker.open(session, CompletedProcedures(steps, saved_keys=not_coupling), wanted=("identified",))
        with pytest.raises(WorkerFailed, match="identified"):
            worker.output("identified")
    finally:
        worker.close()


def test_a_failing_worker_says_why_in_words(tmp_path):
    worker = ReductionWorker.spawn()
    try:
        missing = tmp_path / "none.db"
        worker.open(str(missing), CompletedProcedures(_steps(("r1", "ruler")), saved_keys=["r1"]))
        with pytest.raises(WorkerFailed, match="none.db"):
            worker.finish()
    finally:
        worker.close()
    with pytest.raises(WorkerFailed, match="stopped"):
        worker.finish()                                 # a closed worker: said, not a hang


def test_a_session_run_in_one_go_commands_iso_9283_with_the_model_reduced_beside_it(tmp_path):
    """The TUI's wiring (app.commands.session): one run of every step, the compensated commands from the model the
    worker identified, the results from the worker -- the offline reduction's, number for number."""
    from app.commands.session import _reduced_beside
    from app.demo import build_demo
    db = str(tmp_path / "s.db")
    d = build_demo(db, seed=1)
    reduction = _reduced_beside(d.runner, db, ReductionWorker.spawn())
    try:
        assert d.runner.command.identified == reduction.model
        assert d.runner.run() == "finished"
        got = reduction.results()
        assert reduction.worker is not None                 # the worker made them: it never failed
    finally:
        d.close()
        reduction.close()
    assert got["iso9283"]["compensated"]
    assert _equal(got, reprocess(db)) == []


@pytest.mark.parametrize("cores, load, setting, started", [
    (2, 0.3, "", True), (2, 1.6, "", True), (2, 1.9, "", False), (1, 0.0, "", False), (8, 6.0, "", True),
    (2, 3.0, "1", True), (4, 0.0, "0", False)])
def test_the_worker_starts_only_where_a_core_is_free_for_it(monkeypatch, cores, load, setting, started):
    import app.live_reduction as live
    monkeypatch.setattr(live, "usable_cores", lambda: cores)
    monkeypatch.setattr(live.os, "getloadavg", lambda: (load, load, load))
    monkeypatch.setenv(live.LIVE_ENV, setting)
    monkeypatch.setattr(live.ReductionWorker, "spawn", classmethod(lambda cls: "spawned"))
    assert (live.ReductionWorker.start() == "spawned") is started
