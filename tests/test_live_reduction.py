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
from offline.reduction.context import Located, Reduction
from offline.reduction.live import LiveReduction
from offline.reduction.run import reduce_session
from offline.reduction.session import SessionReader, load_session
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
                             (name, value, "accuracy" in live.ctx.figs,
                              any(e["name"].startswith("ident.") for e in live.ctx.est.items))))
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
    assert not identified[3]        # ... and before the pose set's errors (their eight re-solves)


def test_work_done_ahead_is_the_stages_own(session, monkeypatch):
    """The transmission stage finds its runs' angles and loads computed ahead (``PREPARE``, while it waited for the
    compliance procedure) and the pose set its targets located; the results are still the offline reduction's."""
    from offline.reduction.stages import transmission, poses
    order = [s["procedure"] for s in load_session(session).steps]
    running: list[str] = []
    computed: list[tuple[str, str | None]] = []         # (what, the stage running then)

    def spy(name, fn):
        def wrapped(*a, **k):
            computed.append((name, running[-1] if running else None))
            return fn(*a, **k)
        return wrapped

    def spy_stage(stage):
        def run(ctx, steps):
            running.append(stage.name)
            try:
                return stage_runs[stage.name](ctx, steps)
            finally:
                running.pop()
        return run

    stage_runs = {}
    live = LiveReduction(session, planned=list(dict.fromkeys(order)))
    for i, stage in enumerate(live.stages):
        stage_runs[stage.name] = stage.run
        live.stages[i] = type(stage)(**{**stage.__dict__, "run": spy_stage(stage)})
    monkeypatch.setattr(transmission, "angles_about_own_axis", spy("angles", transmission.angles_about_own_axis))
    import offline.reduction.torques as torques
    monkeypatch.setattr(torques, "series_loads", spy("loads", torques.series_loads))
    monkeypatch.setattr(Located, "_locate", spy("locate", Located._locate))
    for i, proc in enumerate(order):
        if proc not in order[i + 1:]:
            live.read = _as_it_stood(session, i + 1)
            live.complete([proc])
    live.read = load_session
    got = live.finish()
    assert {"transmission", "poses"} <= live.prepared
    assert ("angles", None) in computed and ("loads", None) in computed        # done ahead, in no stage
    assert not [c for c in computed if c[1] in ("transmission", "poses")]     # nothing of it again in the stages
    assert [c for c in computed if c[1] == "compliance"]       # the spies see the stages' own work (can fail)
    assert _equal(got, reduce_session(session)) == []


def test_targets_are_located_one_procedure_at_a_time(session):
    """A step's located targets depend on its procedure's steps only: located with the whole session, procedure by
    procedure as a recording session completes them (in another order, with the steps of the procedures not complete
    yet absent), or by :func:`locate_targets` on that procedure's readings alone -- bit for bit."""
    from calib.estimators.points import locate_targets
    data = load_session(session)
    ctx = run_module.start_reduction(data)
    run_module.run_stage(ctx, all_stages()[0])
    fit = ctx.outputs["stations"]
    whole = Located(data.steps, fit)
    procs = list(dict.fromkeys(s["procedure"] for s in data.steps))
    growing = Located([], fit)
    for p in reversed(procs):
        growing.steps = growing.steps + [s for s in data.steps if s["procedure"] == p]
        growing(growing.steps[-1])
    for p in procs:
        sts = [s for s in data.steps if s["procedure"] == p]
        rows = [{**r, "target": f"{i}/{r['target']}"} for i, s in enumerate(sts) for r in s["readings"]]
        alone = locate_targets(rows, fit) if rows else {}
        for i, st in enumerate(sts):
            a, b = whole(st), growing(st)
            assert a.keys() == b.keys() == {k.split("/", 1)[1] for k in alone if k.split("/", 1)[0] == str(i)}
            for tg in a:
                for x, y, z in zip(a[tg], b[tg], alone[f"{i}/{tg}"]):
                    assert np.array_equal(x, y) and np.array_equal(x, z), (p, st["key"], tg)


def test_a_kept_reader_reads_what_load_session_reads_and_sees_later_commits(session, tmp_path):
    import sqlite3
    db = tmp_path / "s.db"
    shutil.copyfile(session, db)
    def set_coupling(status: str) -> None:
        w = sqlite3.connect(db)
        with w:
            w.execute("UPDATE step SET status=? WHERE procedure='coupling'", (status,))
        w.close()

    set_coupling("skipped")                         # the coupling procedure not recorded yet
    reader = SessionReader()
    first = reader(str(db), ("poses",), ())
    assert _equal(first.steps, load_session(str(db), ("poses",)).steps) == []
    assert reader(str(db), ("coupling",), ()).steps == []
    set_coupling("accepted")                        # ... and now it is
    got = reader(str(db), ("coupling",), ())
    assert got.steps and _equal(got.steps, load_session(str(db), ("coupling",)).steps) == []
    assert got.setup == first.setup and got.session == first.session
    whole, want = reader(str(db), None, ("poses",)), load_session(str(db), None, ("poses",))
    assert _equal(whole.steps, want.steps) == [] and whole.session == want.session and whole.plan == want.plan
    assert whole.setup == want.setup and whole.devices == want.devices
    reader.close()


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
        ours = []                                       # the recorder's own work while the worker ends the results
        got = worker.finish(while_waiting=lambda: ours.append(worker.proc.poll()))
    finally:
        worker.close()
    assert got["session"]["steps_accepted"] == len(steps) and got["robot"] is not None
    assert ours == [None]                               # done once, the worker still at work


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


def test_scoring_prepared_ahead_scores_as_a_fresh_twin(session):
    """The twin, robot and truth modules made while the worker waits (sim.emulate.truth.prepare) score the results as
    a twin built at the end does, bit for bit; they serve one scoring of the same session only."""
    import copy
    from sim.emulate import truth
    data = load_session(session)
    assert data.metadata.get("emulated")
    res = reduce_session(data)
    fresh = truth.score(copy.deepcopy(res), data)
    truth.prepare(data)
    assert len(truth._PREPARED) == 1
    ahead = truth.score(copy.deepcopy(res), data)
    assert not truth._PREPARED                          # taken by that scoring
    assert _equal(ahead, fresh) == []
    assert any(e["truth"] is not None for e in ahead["estimates"])    # scored at all (the test can fail)
