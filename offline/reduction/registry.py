"""The stage registry of the offline reduction, mirroring the procedure registry (:mod:`acq.session.procedures`).

A stage declares the step procedures it reduces, what it needs from other stages (their outputs, by name), what it
gives, and whether it applies to a robot (its :class:`calib.profile.RobotProfile`: the thesis's compensation scheme
applies only where the thesis's formulas hold).  :func:`in_order` puts the stages in dependency order, keeping the
listed order where the dependencies leave a choice; :func:`offline.reduction.run.reduce_session` is then one loop.
Adding a procedure is a procedure module plus a stage module (listed in :mod:`offline.reduction.stages`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable

from calib.errors import RobocalError

if TYPE_CHECKING:                                   # typing only: the context imports this module
    from calib.profile import RobotProfile

    from offline.reduction.context import Reduction

#: exceptions a stage's computation may raise on bad or insufficient readings: the stage is said to have failed and
#: the others still run (anything else is a bug and propagates)
STAGE_ERRORS = (RobocalError, KeyError, ValueError, IndexError)


def always(profile: "RobotProfile") -> bool:
    return True


@dataclass(frozen=True)
class Stage:
    """One reduction stage.

    ``run(ctx, steps)``: the stage's computation on the accepted steps of its ``procedures`` (in the order
    recorded); it adds estimates and figures to ``ctx`` and returns its output (None: nothing).  ``needs``: outputs
    of other stages it reads (``ctx.outputs[name]``); ``reads``: procedures whose steps it reads besides its own
    (``ctx.steps_of``; a reduction running while the session records waits for them too); ``gives``: the name its
    output is kept under.  ``label``: the
    stage in the operator's problem lines (default ``name``).  ``fallback(ctx)``: the output when the stage gives
    none or fails (the ruler's: the set-up's stations).  ``progress``: the share of the whole reduction done after
    it (for a progress bar)."""

    name: str
    run: Callable[["Reduction", list[dict]], Any]
    procedures: tuple[str, ...] = ()
    needs: tuple[str, ...] = ()
    reads: tuple[str, ...] = ()
    gives: str | None = None
    applies: Callable[["RobotProfile"], bool] = always
    label: str = ""
    fallback: Callable[["Reduction"], Any] | None = None
    progress: float | None = None

    @property
    def words(self) -> str:
        return self.label or self.name


def in_order(stages: list[Stage]) -> list[Stage]:
    """The stages in dependency order: each after every stage giving what it needs, otherwise as listed.  A need no
    stage gives, or a circle, is a programming error (said at import, not on a session)."""
    given = {s.gives: s.name for s in stages if s.gives}
    missing = [(s.name, n) for s in stages for n in s.needs if n not in given]
    if missing:
        raise RuntimeError(f"reduction stages: {missing[0][0]} needs {missing[0][1]!r}, which no stage gives")
    done: list[Stage] = []
    left = list(stages)
    while left:
        ready = next((s for s in left if all(given[n] in {d.name for d in done} for n in s.needs)), None)
        if ready is None:
            raise RuntimeError(f"reduction stages: circular needs among {', '.join(s.name for s in left)}")
        done.append(ready)
        left.remove(ready)
    return done
