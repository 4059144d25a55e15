"""The reduction of a session while it is being recorded: each stage runs as soon as every procedure it reads is
complete, so the results are ready when the last step is saved instead of a reduction's time later.

Why it gives the offline result exactly: a stage reads only the accepted steps of its own procedures and the outputs
of the stages before it (:mod:`offline.reduction.registry`), and the stages still run one after another in the
registry's dependency order -- a stage whose procedures are not complete yet holds back the ones after it.  Each
time stages become ready the steps of the procedures completed since are read from the database as committed, and
at the end the session's row and the steps of every procedure not read yet, and the results document is made from
the whole, as :func:`offline.reduction.run.reduce_session` makes it.  ``tests/test_live_reduction.py`` checks the
document against the offline reduction of the same database, number for number.

"Complete" is the recorder's word: it knows its plan (which steps each procedure has) and says which procedures
have every step saved (:meth:`LiveReduction.complete`); a stage with no procedure (a computation on earlier outputs)
runs when its turn comes.

While a stage waits for another's output (the pose set for the transmission and compliance stages, recorded after
it), the work it can do on its own steps is done ahead: a complete procedure is read at once, and a stage module's
``PREPARE`` (:mod:`offline.reduction.stages`) runs as soon as the stage's procedures are complete -- the pose set's
targets located, the transmission runs' angles and loads -- so the stage finds it done
(:meth:`offline.reduction.context.Reduction.keep`: the same function on the same inputs, so the same result).
Targets are located one procedure at a time (:class:`offline.reduction.context.Located`), so locating a procedure
early gives what locating it with the rest of the session gives.
"""
from __future__ import annotations

import time
from dataclasses import replace
from collections.abc import Callable, Iterable

from offline.reduction.context import Reduction
from offline.reduction.registry import STAGE_ERRORS, Stage
from offline.reduction.run import code_provenance, migrate_steps, results_document, run_stage, start_reduction
from offline.reduction.session import SessionData, SessionReader
from offline.reduction.stages import all_stages, preparations


class LiveReduction:
    """The stages of the session at ``path`` run as its procedures complete (see the module docstring)."""

    def __init__(self, path: str, planned: Iterable[str] | None = None, n_mc: int = 0,
                 read: Callable[[str, tuple[str, ...] | None, tuple[str, ...]], SessionData] | None = None,
                 on_output: Callable[[str, object, list[str]], None] | None = None):
        self.path = path
        # called with (name, value, problems so far) as soon as the stage giving an output has run: whoever waits
        # for one output (the pose set's model) has it before the stages after it run
        self.on_output = on_output
        # how the session is read (a test reads it as it stood earlier): by default one connection kept open
        self.read = read if read is not None else SessionReader()
        self.n_mc = n_mc
        self.stages: list[Stage] = all_stages()
        self.prepare = preparations()          # stage name -> the work it can do ahead on its own steps
        self.prepared: set[str] = set()
        # the procedures with every planned step saved; one the plan does not have has none to wait for
        self.done: set[str] = set() if planned is None else \
            {p for s in self.stages for p in (*s.procedures, *s.reads)} - set(planned)
        self.next = 0                           # the index of the first stage not run yet
        self.read_procedures: set[str] = set()  # the procedures whose steps are read
        self.ctx: Reduction | None = None
        self.sent: set[str] = set()             # the outputs handed to on_output already
        self.code: dict | None = None           # the results' code provenance
        self.elapsed_s = 0.0                    # the time spent reducing (not waiting for steps)

    def complete(self, procedures: Iterable[str]) -> list[str]:
        """These procedures have every planned step saved: read them, run the stages that are now ready, in order,
        and the work ahead (``PREPARE``) of the stages still waiting whose procedures are complete.  Returns the
        names of the stages run."""
        self.done |= set(procedures)
        ready = []
        while self.next + len(ready) < len(self.stages) and self._ready(self.stages[self.next + len(ready)]):
            ready.append(self.stages[self.next + len(ready)])
        self._run(ready)
        self._ahead()
        return [s.name for s in ready]

    def output(self, name: str) -> tuple[object | None, list[str]]:
        """The output ``name`` (``identified``: the pose set's model) if its stage has run, and the problems said
        so far; (None, problems) when the stage ran and gave nothing.  A KeyError when it has not run yet."""
        if self.ctx is None or not any(s.gives == name for s in self.stages[:self.next]):
            raise KeyError(f"{name}: its stage has not run yet (procedures still recording)")
        return self.ctx.outputs.get(name), list(self.ctx.problems)

    def finish(self) -> dict:
        """Every remaining stage on the session as recorded in the end; the results document (with its ``trace``),
        as the offline reduction gives it."""
        self._run(self.stages[self.next:], whole=True)
        if isinstance(self.read, SessionReader):
            self.read.close()
        return results_document(self.ctx, self.elapsed_s, self.code)

    def _gave(self, name: str, value, problems: list[str]) -> None:
        if self.on_output is not None and name not in self.sent:
            self.sent.add(name)
            self.on_output(name, value, problems)

    def _ready(self, stage: Stage) -> bool:
        return set(stage.procedures) | set(stage.reads) <= self.done

    def _ahead(self) -> None:
        """The ``PREPARE`` of each stage not run yet whose procedures are complete (once; after the stations are
        known).  What it cannot do (a failure on these readings) is left to the stage, which then meets it itself."""
        if self.ctx is None or self.ctx.outputs.get("stations") is None:
            return
        t0 = time.perf_counter()
        for stage in self.stages[self.next:]:
            fn = self.prepare.get(stage.name)
            if fn is None or stage.name in self.prepared or not set(stage.procedures) <= self.done \
                    or not stage.applies(self.ctx.profile):
                continue
            self.prepared.add(stage.name)
            try:
                fn(self.ctx, self.ctx.steps_of(stage.procedures))
            except STAGE_ERRORS:
                pass
        self.elapsed_s += time.perf_counter() - t0

    def _run(self, stages: list[Stage], whole: bool = False) -> None:
        t0 = time.perf_counter()
        self._read(whole)
        for stage in stages:
            run_stage(self.ctx, stage)
            self.next += 1
            if stage.gives:
                self._gave(stage.gives, self.ctx.outputs.get(stage.gives), list(self.ctx.problems))
        self.elapsed_s += time.perf_counter() - t0

    def _read(self, whole: bool = False) -> None:
        """The steps of the procedures completed since the last read (``whole``: the session row and the steps of
        every procedure not read yet, whatever the plan said); the reduction so far keeps its outputs, estimates,
        located targets, the work done ahead and the steps it read (already in the step vocabulary), in the order
        recorded."""
        new = tuple(sorted(self.done - self.read_procedures))
        if not whole and not new and self.ctx is not None:
            return
        read = tuple(sorted(self.read_procedures))
        data = self.read(self.path, None, read) if whole else self.read(self.path, new, ())
        self.read_procedures |= self.done
        if self.ctx is None:
            self.ctx = start_reduction(data, self.n_mc)
            self.ctx.on_output = self._gave     # a stage's output ready before the stage ends is handed on then
            self.code = code_provenance(data)   # asked now, not when the last step is saved
            return
        migrate_steps(data, self.ctx.robot)
        steps = sorted(self.ctx.data.steps + data.steps, key=lambda st: st["seq"])
        # a read of some procedures brings their steps; the whole read, the session's row as it ended too
        self.ctx.read_again(replace(data if whole else self.ctx.data, steps=steps))
