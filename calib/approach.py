"""Approach directions from the order the poses were measured in (issue 27).

Backlash shows only through the side each joint approached its pose from.  Most pose files do not say it (no
``dir1..dirn`` columns), but many carry the order of measurement: the rows in the order the robot visited them, or a
time column.  Then each joint's approach direction at a pose is the sign of its last move larger than a threshold:
a move smaller than the play does not carry the drive across it, so it does not change the side the link rests on.
The threshold is therefore the smallest play that can be tested (default :data:`DEFAULT_THRESHOLD_DEG` for a
revolute joint, :data:`DEFAULT_THRESHOLD_MM` for a prismatic one) and it is stated with the result.  The first pose
of a session has no earlier move: its direction is 0 (unknown), so it is left out of a backlash term.

Assumption, stated with the result: the robot went straight from each pose to the next (no intermediate moves that
the file does not record).  The placebo -- the direction of the NEXT move -- must carry no signal (tests do that).

``--order`` chooses where the order comes from:

* ``auto`` (default): the file's ``dir*`` columns when it has them; else the time column when there is one
  (``time``, a column named like ``t_start_robot`` (``t_start*``), or ``--time-column NAME``); else none -- rows of a
  file without a time column are not assumed to be in measurement order (a planned pose set is often shuffled,
  and directions made up from a shuffle would offer backlash a placebo);
* ``rows``: the rows are in measurement order;
* ``time``: the time column gives it (it must not go back);
* ``none``: no directions are inferred (the file's ``dir*`` columns, if any, are still read).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from .errors import RobocalError
from .units import DEG

ORDERS = ("auto", "rows", "time", "none")
#: the smallest move that sets a revolute joint's approach side (the smallest play that can be tested)
DEFAULT_THRESHOLD_DEG = 0.5
#: ... and a prismatic joint's
DEFAULT_THRESHOLD_MM = 0.5
#: time columns recognised without --time-column, besides ``time``: the start of a measurement window
_TIME_LIKE = re.compile(r"^t_start\w*$")


@dataclass
class Inferred:
    """Directions inferred from the measurement order, and what they came from (for the output)."""

    direction: np.ndarray          # (N, n) +1 / -1, 0 where unknown (the first pose, a joint that never moved)
    source: str                    # "the time column t_start_robot", "the row order"
    threshold_rad: float
    threshold_mm: float

    def note(self) -> str:
        return (f"approach directions inferred from {self.source}: each joint's last move larger than "
                f"{self.threshold_rad / DEG:g} deg ({self.threshold_mm:g} mm for a prismatic joint), the first pose "
                f"has none; assumes the robot went straight from pose to pose")


def last_moves(q: np.ndarray, prismatic, threshold_rad: float = DEFAULT_THRESHOLD_DEG * DEG,
               threshold_mm: float = DEFAULT_THRESHOLD_MM) -> np.ndarray:
    """(N, n) the sign of each joint's last move larger than its threshold before each pose (rows in measurement
    order); 0 before the first such move.  ``prismatic``: which joints' values are lengths (mm)."""
    q = np.atleast_2d(np.asarray(q, float))
    thr = np.where(np.asarray(prismatic, bool), threshold_mm, threshold_rad)
    step = np.diff(q, axis=0)
    big = np.abs(step) > thr
    out = np.zeros_like(q)
    last = np.zeros(q.shape[1])
    for i in range(1, len(q)):
        last = np.where(big[i - 1], np.sign(step[i - 1]), last)
        out[i] = last
    return out


def time_column(cols: list[str], given: str | None, src: str, header_line: int) -> str | None:
    """The column the measurement time is read from: ``given`` (``--time-column``; one line when the file has no
    such column), else ``time``, else the first ``t_start*`` column, else None."""
    if given is not None:
        if given not in cols:
            raise RobocalError(f"{src}: line {header_line}: --time-column {given}: the file has no such column "
                               f"(columns: {', '.join(cols)})")
        return given
    if "time" in cols:
        return "time"
    return next((c for c in cols if _TIME_LIKE.match(c)), None)


def check_monotonic(t: np.ndarray, lines: list[int], src: str, col: str) -> None:
    """Time must not go back from one row to the next (one session per file): a clock jump, files joined in the
    wrong order or the wrong column would give every later pose a made-up approach direction."""
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise RobocalError(f"{src}: line {lines[i]}: column {col}: time {t[i]:.10g} is earlier than the row before "
                           f"({t[i - 1]:.10g}): the time of one session must not go back")


def infer(q: np.ndarray, prismatic, order: str, *, has_dir: bool, time_col: str | None, time_s=None,
          lines: list[int] | None = None, src: str = "<memory>", threshold_rad: float | None = None,
          threshold_mm: float | None = None) -> Inferred | None:
    """The directions of a pose table in measurement order by ``order`` (see the module docstring), or None when
    none are inferred.  ``time_s``: the values of ``time_col`` per row."""
    if order not in ORDERS:
        raise RobocalError(f"--order: {order!r} is not one of {', '.join(ORDERS)}")
    thr_rad = DEFAULT_THRESHOLD_DEG * DEG if threshold_rad is None else float(threshold_rad)
    thr_mm = DEFAULT_THRESHOLD_MM if threshold_mm is None else float(threshold_mm)
    if not (math.isfinite(thr_rad) and thr_rad > 0 and math.isfinite(thr_mm) and thr_mm > 0):
        raise RobocalError(f"--direction-threshold: must be positive, got {thr_rad / DEG:g} deg, {thr_mm:g} mm")
    if order == "none" or (order == "auto" and (has_dir or time_col is None)):
        return None
    if order == "time" and time_col is None:
        raise RobocalError(f"{src}: --order time: the file has no time column (time, t_start..., or name one with "
                           f"--time-column)")
    if order in ("time", "auto"):
        check_monotonic(np.asarray(time_s, float), list(lines or range(1, len(q) + 1)), src, time_col)
        source = f"the time column {time_col}"
    else:
        source = "the row order"
    if has_dir:
        source += " (--order replaces the file's dir columns)"
    return Inferred(last_moves(q, prismatic, thr_rad, thr_mm), source, thr_rad, thr_mm)
