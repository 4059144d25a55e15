"""The session runner: drives the procedures' steps against the rig, checks, asks the operator, stores.

API for front ends (the headless one in :mod:`acq.session.headless`, the Textual TUI of issue 7)
=================================================================================================

Build: ``runner = Runner(store, rig, steps, operator, bench=ManualBench(), stations=..., predict=..., limits=...,
refit_stations=..., preflight=...)`` (:func:`app.demo.build_demo` shows a complete wiring).  With
``preflight`` (:class:`acq.session.preflight.Preflight`) the runner refuses to start while any remaining step fails
it (state ``refused``, a ``preflight`` event with one line per step), and checks each step again with the current
stations before asking for it (a failing step can only be skipped).  ``refit_stations(store)`` (e.g.
:func:`acq.session.stations.stations_from_store` with the setup bound) is called at start and after every saved
ruler step; once it returns stations, later miss-distance checks use them with the noise-based limit (see
:mod:`acq.session.checks`).  Then either ``runner.run()`` (blocking, in the
calling thread) or ``runner.start()`` (a worker thread; ``runner.join()``).  All device I/O happens in the runner's
thread, never in the UI thread.

**Events** (runner -> UI): ``runner.subscribe(callback)`` registers ``callback(event)``; it is called *in the runner
thread*, so a Textual app should forward with ``app.post_message(...)`` (``call_from_thread`` is fine too).  A
subscriber exception is logged and ignored.  For polling UIs, ``runner.events`` is a ``queue.SimpleQueue`` of the
same objects (``get``/``get_nowait``/``empty``; C-implemented: a session emits thousands of events, mostly unread).  Every event is an :class:`Event` with ``kind`` and ``data`` (a JSON-able dict):

=====================  ==================================================================================
kind                   data
=====================  ==================================================================================
``state``              ``{"old", "new"}``; states: idle, running, waiting (for the operator), paused, finished,
                       aborted, failed, refused (the pre-flight failed: nothing ran, nothing was written)
``preflight``          ``{"lines"}``: one line per step that fails the pre-flight (:mod:`acq.session.preflight`)
``session``            ``{"guid", "path", "resumed", "done", "total"}`` once at start
``step_started``       ``{"key", "procedure", "title", "instruction", "index", "total", "attempt", "pose_deg",
                       "targets", "inputs"}``
``step_skipped_done``  ``{"key"}``: already committed in an earlier run (resume)
``reading``            ``{"key", "station", "target", "face", "repeat", "hz_deg", "v_deg"}``
``encoders``           ``{"key", "n_samples", "joint_deg"}``
``check``              ``{"key", "name", "passed", "value", "limit", "unit", "message"}``: every check, a device
                       fault (``device``), a value not entered and a failing pre-flight of the step included
``step_saved``         ``{"key", "status", "attempts"}``: committed to the database (show "saved" only now)
``log``                ``{"text"}``
``finished``           ``{"exit_status", "error"}``
=====================  ==================================================================================

**Answers** (UI -> runner): the runner calls ``operator.ask(request) -> Answer`` in its thread and blocks until it
returns; a UI implements ``ask`` by posting the request to the app and waiting on a ``concurrent.futures.Future`` the
app completes (``ask`` should return ``Answer("abort")`` if the app closes).  :class:`Request` has ``kind``:

* ``"setup"``: before a step's acquisition -- do what ``instruction`` says and enter ``inputs`` (loads, gauges);
  answer ``continue`` (with ``values``), ``skip``, ``pause`` or ``abort``.  Every input must be in ``values``: the
  plan's value (``InputSpec.suggested``) is a hint, never a stand-in, so an input left out fails the attempt (an
  ``entered ...`` check, nothing acquired, choices ``repeat``/``skip``/``pause``/``abort``), and an entry further
  from the plan than ``InputSpec.tolerance`` fails the ``as planned ...`` check, naming both values;
* ``"decision"``: after the checks (``checks`` lists them) -- answer ``accept``, ``repeat``, ``skip``, ``pause``,
  ``abort``; ``note`` is stored with the step.

``pause`` leaves the step uncommitted and ends :meth:`Runner.run` with state ``paused`` (session ``exit_status``
'paused'); calling ``run()`` again (or a new runner on the same database) resumes at the first step not committed.
``runner.request_pause()`` (any thread) pauses at the next step boundary; ``runner.request_abort()`` aborts there.
A crash is the same as a pause without the status: the next run resumes after the last committed step.
"""
from __future__ import annotations

import logging
import queue
import threading
import time
import traceback
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from calib.errors import RobocalError
from calib.units import DEG

from ..errors import DeviceError

from . import checks as ck
from .preflight import failing_lines
from .procedures import procedure_info
from .rig import Bench, ManualBench, Rig, mean_rows
from .steps import Capture, Sight, Step
from .store import SessionStore, StepRecord

log = logging.getLogger(__name__)

ACTIONS_SETUP = ("continue", "skip", "pause", "abort")
ACTIONS_DECISION = ("accept", "repeat", "skip", "pause", "abort")
ACTIONS_FAULT = ("skip", "pause", "abort")
#: an attempt that acquired nothing (a device fault, a value not entered): nothing to accept
ACTIONS_RETRY = ("repeat", "skip", "pause", "abort")


@dataclass
class _Acquired:
    """One attempt's acquisition: readings and the encoder capture."""

    attempt: int
    rows: list = field(default_factory=list)
    cap: object = None


@dataclass
class _StepLog:
    """What a step has gathered over its attempts (every attempt is stored; the last one is the step's data)."""

    started: float
    attempt: int = 0
    readings: list = field(default_factory=list)
    chunks: list = field(default_factory=list)
    inputs: list = field(default_factory=list)
    checks: list = field(default_factory=list)

    def add_inputs(self, step: Step, ans: "Answer") -> dict:
        """The operator's values for the step's inputs (stored with the attempt); returns them by name."""
        values = {i.name: float(ans.values[i.name]) for i in step.inputs if ans.values.get(i.name) is not None}
        for spec in step.inputs:
            if spec.name in values:
                self.inputs.append({"attempt": self.attempt, "name": spec.name, "value": values[spec.name],
                                    "unit": spec.unit, "t_wall_s": time.time()})
        if ans.note:
            self.inputs.append({"attempt": self.attempt, "name": "note", "value": None, "text": ans.note,
                                "t_wall_s": time.time()})
        return values

    def add_acquisition(self, rows: list, cap, tap_device_id: int) -> None:
        self.readings += rows
        if cap is not None:
            self.chunks.append({"attempt": self.attempt, "device_id": tap_device_id, "phase": "settle",
                                "seq": cap.seq, "t_device_us": cap.t_device_us, "t_mono_s": cap.t_mono_s,
                                "counts_wire": cap.counts_wire, "counts": cap.counts})


@dataclass
class Event:
    kind: str
    data: dict


@dataclass
class Request:
    kind: str                      # setup | decision
    step: Step
    attempt: int
    choices: tuple[str, ...]
    checks: list = field(default_factory=list)      # list[checks.Check] for decisions


@dataclass
class Answer:
    action: str
    values: dict = field(default_factory=dict)      # operator inputs by InputSpec.name
    note: str = ""


class Operator(Protocol):
    def ask(self, request: Request) -> Answer: ...


class Runner:
    def __init__(self, store: SessionStore, rig: Rig, steps: list[Step], operator: Operator, *,
                 bench: Bench | None = None, stations: dict | None = None,
                 predict: Callable[[Step], dict] | None = None, limits: dict | None = None,
                 capture_s: float = 0.02, settle_s: float = 0.0,
                 refit_stations: Callable[[SessionStore], dict | None] | None = None, preflight=None,
                 command: Callable[[Step], Step] | None = None):
        self.store = store
        self.rig = rig
        self.steps = steps
        self.operator = operator
        self.bench = bench or ManualBench()
        self.stations = stations or {}
        self.predict = predict
        self.limits = {**ck.DEFAULT_LIMITS, **(limits or {})}
        self.capture_s = capture_s
        self.settle_s = settle_s
        self.refit_stations = refit_stations
        self.preflight = preflight          # acq.session.preflight.Preflight (or anything with check/check_step)
        self.command = command              # a step's joint command computed when it is reached (ISO 9283's "on")
        self.stations_fitted = False        # True once the stations come from the session's own ruler sightings
        self.events: queue.SimpleQueue = queue.SimpleQueue()
        self.state = "idle"
        self._subs: list[Callable[[Event], None]] = []
        self._pause = threading.Event()
        self._abort = threading.Event()
        self._thread: threading.Thread | None = None

    # -- wiring ------------------------------------------------------------------------------------------------
    def subscribe(self, cb: Callable[[Event], None]) -> None:
        self._subs.append(cb)

    def emit(self, kind: str, **data) -> None:
        ev = Event(kind, data)
        self.events.put(ev)
        for cb in list(self._subs):
            try:
                cb(ev)
            except Exception:          # a UI bug must not stop acquisition
                log.exception("event subscriber failed")

    def _set_state(self, new: str) -> None:
        old, self.state = self.state, new
        self.emit("state", old=old, new=new)

    def request_pause(self) -> None:
        self._pause.set()

    def request_abort(self) -> None:
        self._abort.set()

    def start(self) -> threading.Thread:
        self._thread = threading.Thread(target=self.run, name="session-runner", daemon=True)
        self._thread.start()
        return self._thread

    def join(self, timeout: float | None = None) -> None:
        if self._thread is not None:
            self._thread.join(timeout)

    # -- the loop ----------------------------------------------------------------------------------------------
    def run(self) -> str:
        """Run every step not yet committed; returns the final state (finished, paused, aborted, failed)."""
        self._pause.clear()
        done = self.store.done_keys()
        if self.preflight is not None:
            lines = failing_lines(self.preflight.check([s for s in self.steps if s.key not in done]))
            if lines:
                return self._refuse(lines)
        prime = getattr(self.predict, "prime", None)
        if prime is not None:                   # the predictions of every step to run, in one evaluation per target
            prime([s for s in self.steps if s.key not in done])
        row = self.store.session_row()
        resumed = bool(done) or row["exit_status"] is not None
        if row["exit_status"] is not None or done:
            self.store.reopen()
        self._set_state("running")
        self.emit("session", guid=self.store.guid, path=self.store.path, resumed=resumed, done=len(done),
                  total=len(self.steps))
        try:
            self._refit()               # a resumed session already has its ruler steps
            for i, step in enumerate(self.steps):
                if step.key in done:
                    self.emit("step_skipped_done", key=step.key)
                    continue
                if self._abort.is_set():
                    return self._end("aborted", "abort", "aborted by request")
                if self._pause.is_set():
                    return self._end("paused", "paused", None)
                outcome = self._run_step(i, step)
                if outcome in ("pause", "abort"):
                    return self._end("paused" if outcome == "pause" else "aborted",
                                     "paused" if outcome == "pause" else "abort", None)
            return self._end("finished", "success", None)
        except Exception as exc:
            self.emit("log", text=traceback.format_exc())
            return self._end("failed", "fail", f"{type(exc).__name__}: {exc}")

    def _refuse(self, lines: list[str]) -> str:
        """The pre-flight failed: say why, one line per step, and leave the session as it is (nothing recorded is
        touched, a resumed session keeps its state)."""
        self.emit("preflight", lines=lines)
        for ln in lines:
            self.emit("log", text=f"pre-flight: {ln}")
        self._set_state("refused")
        error = f"pre-flight failed for {len(lines)} step(s), first {lines[0]}"
        self.emit("finished", exit_status="refused", error=error)
        return "refused"

    def _end(self, state: str, exit_status: str, error: str | None) -> str:
        self.store.finish(exit_status, error)
        self._set_state(state)
        self.emit("finished", exit_status=exit_status, error=error)
        return state

    def _run_step(self, index: int, step: Step) -> str:
        """One step: setup prompt, acquisition, checks, decision -- repeated until accepted, skipped, paused or
        aborted -- then the step is committed.  Returns the outcome (accepted, skipped, pause, abort)."""
        rec = _StepLog(time.time())
        planned = step
        step, blocked = self._commanded(planned)
        blocked = blocked or self._preflight_step(step)
        while True:
            rec.attempt += 1
            self._emit_started(index, step, rec.attempt)
            if blocked:
                action, note = self._decide(step, rec, blocked, ACTIONS_FAULT)
                if action in ("pause", "abort"):
                    return action
                if action == "repeat":              # the operator changed something: check again
                    step, blocked = self._commanded(planned)
                    blocked = blocked or self._preflight_step(step)
                    continue
                status = "skipped"
                break
            ans = self._ask(Request("setup", step, rec.attempt, ACTIONS_SETUP))
            if ans.action in ("pause", "abort"):
                return ans.action
            if ans.action == "skip":
                status, note = "skipped", ans.note
                break
            results, choices = self._attempt(step, rec, rec.add_inputs(step, ans))
            action, note = self._decide(step, rec, results, choices)
            if action in ("pause", "abort"):
                return action
            if action != "repeat":
                status = "skipped" if action == "skip" else "accepted"
                break
        self._commit(step, rec, status, note)
        return status

    def _attempt(self, step: Step, rec: "_StepLog", values: dict) -> tuple[list, tuple[str, ...]]:
        """One acquisition with the operator's ``values``: (the checks, the choices the operator then has).

        An attempt acquires nothing -- and offers nothing to accept -- when a measured value the step needs was not
        entered (the plan's value is no stand-in for it) or a device fails; the operator fixes it and repeats."""
        missing = ck.missing_inputs(step, values)
        if missing:
            self._emit_checks(step, missing)
            return missing, ACTIONS_RETRY
        self.bench.prepare(step, values)
        try:
            got, cap = self._acquire(step, rec.attempt)
        except DeviceError as exc:
            # an unplugged or silent device fails this attempt, not the session: the operator fixes the cause
            # and repeats (the drivers reconnect), or skips, or pauses; nothing of this attempt is recorded
            results = [ck.Check("device", False, None, None, "",
                                f"{exc} — check the cable and power of that device, then repeat (r)")]
            self._emit_checks(step, results)
            return results, ACTIONS_RETRY
        rec.add_acquisition(got, cap, self.rig.device_ids.get("encoder tap", 0))
        return self._check(step, got, cap, values), ACTIONS_DECISION

    def _emit_started(self, index: int, step: Step, attempt: int) -> None:
        self.emit("step_started", key=step.key, procedure=step.procedure, title=step.title,
                  instruction=step.instruction, index=index, total=len(self.steps), attempt=attempt,
                  pose_deg=step.pose_deg, targets=[t.name for t in step.targets],
                  inputs=[i.name for i in step.inputs])

    def _ask(self, request: Request) -> Answer:
        self._set_state("waiting")
        ans = self.operator.ask(request)
        self._set_state("running")
        return ans

    def _decide(self, step: Step, rec: "_StepLog", results: list, choices: tuple[str, ...]) -> tuple[str, str]:
        """Record the attempt's checks and ask the operator what to do with them: (action, note)."""
        rec.checks += [c.as_row(rec.attempt) for c in results]
        ans = self._ask(Request("decision", step, rec.attempt, choices, results))
        return ans.action, ans.note

    def _commit(self, step: Step, rec: "_StepLog", status: str, note: str) -> None:
        self.store.write_step(StepRecord(step.key, step.procedure, step.title, step.instruction, status, rec.attempt,
                                         rec.started, time.time(), step.spec(), note, rec.readings, rec.chunks,
                                         rec.inputs, rec.checks))
        self.emit("step_saved", key=step.key, status=status, attempts=rec.attempt)
        if status == "accepted" and procedure_info(step.procedure).refits_stations:
            self._refit()

    def _commanded(self, step: Step) -> tuple[Step, list]:
        """The step as it will be commanded: a step whose ``setup["command"]`` names a computed command (the
        calibrated model's, ``compensated``) gets it from the ``command`` hook now -- the stored step then holds
        the command actually sent.  Without the hook, or when it cannot compute one (no calibrated model yet), the
        step is blocked with the reason (the operator can skip it)."""
        if not step.setup.get("command"):
            return step, []
        try:
            if self.command is None:
                raise RobocalError(f"{step.key}: needs the {step.setup['command']} command and this session has no "
                                   "calibrated model to compute it")
            return self.command(step), []
        except RobocalError as exc:
            out = [ck.Check("command", False, None, None, "", str(exc))]
            self._emit_checks(step, out)
            return step, out

    def _preflight_step(self, step: Step) -> list:
        """The pre-flight of this step with the stations as they are now (the ruler refit changes them): failing
        checks block the step (the operator can skip it, pause or abort)."""
        if self.preflight is None:
            return []
        self.preflight.stations = self.stations or self.preflight.stations
        out = [ck.Check(f"pre-flight {f.check}", False, f.value, f.limit, f.unit, f.detail)
               for f in self.preflight.check_step(step)]
        self._emit_checks(step, out)
        return out

    def _refit(self) -> None:
        """Stations from the ruler steps saved so far (when the hook can fit them): tighter miss-distance checks."""
        if self.refit_stations is None:
            return
        st = self.refit_stations(self.store)
        if st is not None:
            first = not self.stations_fitted
            self.stations, self.stations_fitted = st, True
            if first:
                self.emit("log", text="stations refitted from the ruler sightings: miss-distance checks now use "
                                      "the reading-noise limit")

    def _acquire(self, step: Step, attempt: int):
        """Perform the step's acquisition commands (the physical ones -- move, hang -- the bench did in
        ``prepare``; the operator's -- ask, gauges -- came with the setup answer): (readings, encoder capture)."""
        acq = _Acquired(attempt)
        for cmd in step.commands():
            handler = self._HANDLERS.get(type(cmd))
            if handler is not None:
                handler(self, step, cmd, acq)
        if step.faces:
            for st in self.rig.theodolites:
                self.rig.face(st, 1)
        return acq.rows, acq.cap

    def _do_capture(self, step: Step, cmd: Capture, acq: "_Acquired") -> None:
        if self.rig.tap is None:
            return
        cap = acq.cap = self.rig.capture(self.capture_s, self.settle_s)
        jd = (mean_rows(cap.joint_rad) / DEG).tolist() if cap.n else []
        self.emit("encoders", key=step.key, n_samples=cap.n, joint_deg=jd)

    def _do_sight(self, step: Step, cmd: Sight, acq: "_Acquired") -> None:
        tg = cmd.target
        self.bench.aim(tg)
        for rep in range(cmd.repeats):
            for face in cmd.faces:
                for st in self.rig.theodolites:            # the stations as the rig (the set-up) names them
                    self.rig.face(st, face)
                    r = self.rig.sight(st)
                    did = self.rig.device_ids.get(f"theodolite {st}", 0)
                    acq.rows.append({"attempt": acq.attempt, "device_id": did, "station": st, "target": tg.name,
                                     "face": face, "repeat": rep, "hz_rad": r.hz_rad, "v_rad": r.v_rad,
                                     "t_wall_s": r.t_wall, "t_mono_s": r.t_mono, "command": r.command,
                                     "warnings": ",".join(r.warnings), "raw": r.raw})
                    self.emit("reading", key=step.key, station=st, target=tg.name, face=face, repeat=rep,
                              hz_deg=r.hz_rad / DEG, v_deg=r.v_rad / DEG)

    #: the runner's part of the command vocabulary (Ask, Move, Hang and ReadGauges happen at the setup prompt and in
    #: ``bench.prepare``)
    _HANDLERS = {Capture: _do_capture, Sight: _do_sight}

    def _check(self, step: Step, rows: list[dict], cap, values: dict | None = None) -> list[ck.Check]:
        out: list[ck.Check] = []
        if rows:
            out += ck.face_agreement(rows, self.limits["face_agreement_arcsec"])
            out += ck.repeat_spread(rows, self.limits["repeat_spread_arcsec"])
            if self.stations:
                pred = self.predict(step) if self.predict else {}
                out += ck.miss_and_plausibility(rows, self.stations, pred, self.limits, fitted=self.stations_fitted)
        if cap is not None:
            out += ck.encoders_settled(cap, step.pose_deg, self.limits)
        out += ck.inputs_as_planned(step, rows, values or {}, self.limits)
        for extra in procedure_info(step.procedure).checks:
            out += extra(step, rows, values or {}, self.limits)
        self._emit_checks(step, out)
        return out

    def _emit_checks(self, step: Step, results: list) -> None:
        for c in results:
            self.emit("check", key=step.key, name=c.name, passed=c.passed, value=c.value, limit=c.limit, unit=c.unit,
                      message=c.message)
