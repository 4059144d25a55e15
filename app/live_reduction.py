"""The session's reduction in a second process while the session records: each stage runs as soon as its procedures
are complete (:class:`offline.reduction.live.LiveReduction`), so the results are ready when the last step is saved.

Why a process and not a thread: the reduction and the recording are both Python, and one interpreter runs Python on
one core at a time; a second process has its own, and on a machine with two cores or more the reduction then costs
the recording nothing (the demo's 0.7 s of reprocessing left its critical path).  The worker is started before the
session is built, so its imports overlap the recorder's; it reads the session database read-only, as committed
(the recorder writes it in WAL mode: a reader never blocks it), and never writes.

The protocol: pickled tuples over the worker's standard input and output. The recorder sends ``("open", path,
planned procedures, complete procedures, its command line, wanted outputs)``, ``("complete", procedures)`` as
procedures finish, ``("awaiting", name)`` when it needs a wanted output, and ``("finish",)``; the worker sends
``("output", name, (value, problems), warnings)`` for each wanted output as soon as its stage has run (the pose
set's model, for ISO 9283's compensated run: the stages after it do not delay it), ``("results", None, document,
warnings)`` after ``finish`` (the results document, scored against the twin for an emulated session, as
:func:`app.reprocess.reprocess` gives it), or ``("error", None, text, [])`` when it fails, and then ends. Anything
going wrong with the worker -- it could not start, died, or failed -- is a :class:`WorkerFailed`: the recorder says
so in one line and reduces the session itself, as before; nothing recorded depends on the worker.

The worker is started only when a core is free for it (:func:`spare_core`: two cores or more, and the load
average leaves a quarter of one): on a busy machine a second process would only take the recorder's time.
``ROBOCAL_LIVE_REDUCTION=0`` turns it off (the reduction then runs in the recording process after the session, as
it does on a machine with one core), ``ROBOCAL_LIVE_REDUCTION=1`` starts it whatever the load.
"""
from __future__ import annotations

import gc
import os
import pickle
import signal
import subprocess
import sys
import warnings
from collections.abc import Callable, Iterable
from typing import ContextManager
from pathlib import Path

from calib.errors import RobocalError
from calib.threads import usable_cores

#: the variable that turns the worker off ("0") or on whatever the machine's load ("1")
LIVE_ENV = "ROBOCAL_LIVE_REDUCTION"
#: the worker is started when the cores this process may use less the load average (1 minute) leave at least this
#: much of a core (demos run back to back keep it near 1.4 on 2 cores themselves): on a busy machine a second
#: process only takes the recorder's time (on 2 cores with two other processes running, the demo was 0.5-0.7 s
#: slower with the worker than reducing after the session)
SPARE_CORE = 0.25


class WorkerFailed(Exception):
    """The reduction worker could not give what was asked (its reason in words)."""


class CompletedProcedures:
    """Which procedures have every planned step saved, from the runner's events (``step_saved``,
    ``step_skipped_done``): a skipped step is saved too (as skipped), so its procedure still completes."""

    def __init__(self, steps, saved_keys: Iterable[str] = ()):
        self.procedure_of = {s.key: s.procedure for s in steps}
        self.planned = list(dict.fromkeys(s.procedure for s in steps))
        saved = set(saved_keys)
        self.left: dict[str, set[str]] = {}
        for s in steps:
            if s.key not in saved:
                self.left.setdefault(s.procedure, set()).add(s.key)

    @property
    def complete(self) -> list[str]:
        return [p for p in self.planned if p not in self.left]

    def saved(self, key: str) -> list[str]:
        """Step ``key`` is saved: the procedures it completes (none, or its own)."""
        proc = self.procedure_of.get(key)
        keys = self.left.get(proc)
        if keys is None or key not in keys:
            return []
        keys.discard(key)
        if keys:
            return []
        del self.left[proc]
        return [proc]


class SessionReduction:
    """A recording session's reduction, for any front end (the demo, the TUI): by a worker process while the runner
    records (``worker``, see the module docstring), else -- no worker, or it failed -- by this process when asked.
    ``tell``: how a failing worker is said to the operator (one line); ``progress``: a context manager giving a
    progress callback for a reduction in this process (None: none shown)."""

    def __init__(self, runner, db: str, worker: ReductionWorker | None, tell: Callable[[str], None] | None = None,
                 progress: Callable[[], ContextManager] | None = None):
        self.worker, self.db = worker, db
        self.tell = tell or _say
        self.progress = progress
        self._before: dict | None = None        # without a worker: the reduction made before the compensated run
        if worker is not None:
            tracker = CompletedProcedures(runner.steps, runner.store.done_keys())

            def saw(ev) -> None:
                if ev.kind in ("step_saved", "step_skipped_done") and self.worker is not None:
                    self._guard(lambda: self.worker.complete(tracker.saved(ev.data["key"])))

            self._guard(lambda: worker.open(db, tracker, wanted=("identified",)))
            runner.subscribe(saw)

    def model(self) -> dict | None:
        """The pose set's calibrated model document (None: the pose set gave none)."""
        if self.worker is not None:
            got = self._guard(lambda: self.worker.output("identified"))
            if got is not None:
                return got[0]
        self._before = self._reprocess()
        return self._before.get("robot")

    def results(self, while_waiting: Callable[[], None] | None = None) -> dict:
        """The results document of the session as recorded.  ``while_waiting``: work of this process's own to do
        while the worker makes them (the demo loads what prints them)."""
        if self.worker is not None:
            got = self._guard(lambda: self.worker.finish(while_waiting))
            if got is not None:
                return got
        if self._before is not None:            # reduced before the compensated run: only ISO 9283's figures change
            from offline.iso_commands import iso_after_compensated_run
            iso_after_compensated_run(self._before, self.db)
            return self._before
        return self._reprocess()

    def close(self) -> None:
        if self.worker is not None:
            self.worker.close()

    def _reprocess(self) -> dict:
        from app.reprocess import reprocess
        if self.progress is None:
            return reprocess(self.db)
        with self.progress() as update:
            return reprocess(self.db, progress=update)

    def _guard(self, call):
        """``call()``; a failing worker is said in one line and left: this process reduces instead."""
        try:
            return call()
        except WorkerFailed as exc:
            self.tell(f"{exc}; the session is reduced in this process instead")
            self.worker.close()
            self.worker = None
            return None


def _say(text: str) -> None:
    from app.interrupt import say
    say(text)


class ReductionWorker:
    """The recorder's handle on the worker process (see the module docstring)."""

    def __init__(self, proc: subprocess.Popen):
        self.proc = proc

    @classmethod
    def start(cls) -> "ReductionWorker | None":
        """A worker importing the reduction while the session is built; None where it would not help (one core, no
        spare core for it: :data:`SPARE_CORE`; or :data:`LIVE_ENV` set to 0) or could not start."""
        setting = os.environ.get(LIVE_ENV, "").strip()
        if setting == "0" or (setting != "1" and not spare_core()):
            return None
        try:
            return cls.spawn()
        except OSError:
            return None

    @classmethod
    def spawn(cls) -> "ReductionWorker":
        """The worker process, started now: this interpreter running :func:`main` of this very code (its folder first
        on the worker's path, whatever the environment would import)."""
        root = str(Path(__file__).resolve().parents[1])
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])))
        return cls(subprocess.Popen([sys.executable, "-m", "app.live_reduction"], stdin=subprocess.PIPE,
                                    stdout=subprocess.PIPE, env=env))

    def open(self, path: str, tracker: CompletedProcedures, wanted: tuple[str, ...] = ()) -> None:
        """Reduce the session at ``path`` as ``tracker`` says its procedures complete; each output in ``wanted`` is
        sent as soon as its stage has run (read it with :meth:`output`)."""
        self._send("open", path, tracker.planned, tracker.complete, sys.argv, wanted)

    def complete(self, procedures: list[str]) -> None:
        if procedures:
            self._send("complete", procedures)

    def output(self, name: str):
        """The output ``name`` (one of ``wanted``) and the problems said until it was made: (value or None,
        problems).  Waits for its stage; a stage that cannot run yet (a procedure it reads is not complete) is a
        :class:`WorkerFailed`, not a wait for ever."""
        self._send("awaiting", name)
        return self._receive(("output", name))

    def finish(self, while_waiting: Callable[[], None] | None = None) -> dict:
        """The results document of the whole session (its stages not yet run run now); ``while_waiting`` is called
        once the worker is asked, before its answer is awaited."""
        self._send("finish")
        if while_waiting is not None:
            while_waiting()
        return self._receive(("results", None))

    def close(self) -> None:
        """Stop the worker (it is done, or the session was interrupted)."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        for f in (self.proc.stdin, self.proc.stdout):
            try:
                f.close()
            except OSError:
                pass

    def _send(self, *msg) -> None:
        try:
            pickle.dump(msg, self.proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self.proc.stdin.flush()
        except (OSError, ValueError) as exc:
            raise WorkerFailed(f"the reduction worker stopped ({exc})") from None

    def _receive(self, which: tuple[str, str | None]):
        """The value of the message ``which`` (kind, name), reading past the ones sent before it (an output sent
        that nobody waits for any more)."""
        while True:
            try:
                kind, name, value, said = pickle.load(self.proc.stdout)
            except (EOFError, OSError, ValueError, pickle.UnpicklingError) as exc:
                raise WorkerFailed(f"the reduction worker stopped (exit status {self.proc.poll()}, "
                                   f"{exc or 'no reply'})") from None
            if kind == "error":
                raise WorkerFailed(value)
            for category, text in said:         # the worker's warnings, shown as this process's own
                warnings.warn(text, category, stacklevel=3)
            if (kind, name) == which:
                return value


def spare_core() -> bool:
    """Whether a core is free for a second process: two or more cores, and the load average leaves
    :data:`SPARE_CORE` of one (where the system gives no load average, the cores alone say)."""
    cores = usable_cores()
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):           # not a Unix
        load = 0.0
    return cores >= 2 and cores - load >= SPARE_CORE


def serve(inp, out, opened: Callable[[], None] | None = None) -> None:
    """The worker's loop: messages from ``inp``, messages to ``out`` (binary streams), until the end of the input or
    ``finish``.  A failure is sent as an ``error`` message and ends the worker.  ``opened``: called once the session
    is opened (the worker's modules imported), while the recorder records and the worker waits."""
    from offline.reduction.live import LiveReduction
    import numpy.ma, numpy.random  # noqa: F401,E401 -- stages reach them through numpy's lazy attributes: loaded
    # here, while the recorder builds its session, not when the pose set's model is awaited
    live: LiveReduction | None = None
    wanted: tuple[str, ...] = ()

    def send(kind: str, name: str | None, value, said: list) -> None:
        pickle.dump((kind, name, value, said), out, protocol=pickle.HIGHEST_PROTOCOL)
        out.flush()

    def sent(name: str, value, problems: list[str]) -> None:
        if name in wanted:
            send("output", name, (value, problems), [(w.category, str(w.message)) for w in seen])
            seen.clear()

    while True:
        # what the worker holds now (its modules, the reduction so far) lives until it ends: out of the collector's
        # sight, a collection scans only what the next stages allocate -- a full one over everything took 30-40 ms,
        # at random, sometimes between the compliance procedure's last step and the pose set's model (a cycle left
        # as garbage by then is never freed: a worker lives for one session)
        gc.freeze()
        try:
            msg = pickle.load(inp)
        except EOFError:
            return
        kind, args = msg[0], msg[1:]
        with warnings.catch_warnings(record=True) as seen:
            try:
                if kind == "open":
                    # the provenance's command is the recorder's
                    path, planned, complete, sys.argv[:], wanted = args
                    live = LiveReduction(path, planned=planned, on_output=sent)
                    live.complete(complete)
                    if opened is not None:
                        opened()
                    _prepare_scoring(live.ctx.data)
                elif kind == "complete":
                    live.complete(args[0])
                elif kind == "awaiting":
                    if args[0] not in live.sent:    # else sent already
                        raise WorkerFailed(f"{args[0]}: its stage waits for steps not recorded yet")
                elif kind == "finish":
                    res = _scored(live.finish(), live.ctx.data)
                    send("results", None, res, [(w.category, str(w.message)) for w in seen])
                    return
                else:
                    raise WorkerFailed(f"unknown message {kind!r}")
            except Exception as exc:            # noqa: BLE001 -- said to the recorder, which reduces itself
                # robocal's own words as they are; anything else (a bug the recorder's own reduction then meets
                # again, with robocal's internal-error report) with its kind
                why = str(exc) if isinstance(exc, (WorkerFailed, RobocalError)) else f"{type(exc).__name__}: {exc}"
                send("error", None, f"the reduction worker failed: {why}", [])
                return


def _prepare_scoring(data) -> None:
    """An emulated session's twin built and the truth modules imported while the worker waits for steps (what
    :func:`_scored` needs besides the results, :func:`sim.emulate.truth.prepare`), not after the last step."""
    if data.metadata.get("emulated"):
        from sim.emulate.truth import prepare
        prepare(data)


def _scored(res: dict, data) -> dict:
    from app.reprocess import scored
    return scored(res, data)


def main() -> None:
    """The worker process: its standard output carries the protocol only (anything printed goes to its standard
    error), Ctrl-C is the recorder's to handle (the recorder stops the worker)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from app import dataclass_code
    table = dataclass_code.install()            # the reduction's dataclasses from the compiled code kept, as robocal's
    out = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    # the methods new to the table written while the worker waits for steps, not at its exit: the recorder stops
    # the worker as soon as it has the results
    try:
        serve(sys.stdin.buffer, out, opened=table.write if table is not None else None)
    except (BrokenPipeError, ConnectionError):  # the recorder is gone (killed, its terminal closed): nobody to tell
        pass


if __name__ == "__main__":
    main()
