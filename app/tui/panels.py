"""Text of the TUI's panels, as pure functions of plain data: labelled live readings, plan labels that fit their
column, per-procedure progress and the time estimate of the header.

Why apart from the app: what the operator reads must be right at every terminal size, and a pure function can be
tested at every width without starting an app.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


def shorten(text: str, width: int) -> str:
    """``text`` cut to ``width`` characters with an ellipsis (the full text is shown when the node is highlighted)."""
    if width <= 1:
        return text[:max(width, 0)]
    return text if len(text) <= width else text[: width - 1].rstrip() + "…"


def face_name(face) -> str:
    return {1: "I", 2: "II"}.get(face, str(face) if face is not None else "?")


def theodolite_lines(readings: dict[str, dict]) -> list[str]:
    """One line per station, in station order: ``theodolite A  Hz 123.45678°  V 89.12345°  face I  P``."""
    lines = []
    for name in sorted(readings):
        r = readings[name]
        lines.append(f"theodolite {name}  Hz {r['hz_deg']:10.5f}°  V {r['v_deg']:9.5f}°  face {face_name(r.get('face')):<2} "
                     f" target {r.get('target', '')}")
    return lines


def joint_table(counts, joint_rad, width: int = 80) -> list[str]:
    """Encoder counts and joint angles labelled per joint; the columns wrap to the panel's width."""
    n = len(counts) if counts is not None else len(joint_rad)
    col = 10
    label = 7
    per_row = max(1, (max(width, label + col) - label) // col)
    lines = []
    for start in range(0, n, per_row):
        idx = range(start, min(n, start + per_row))
        lines.append("joint  " + "".join(f"{'J' + str(j + 1):>{col}}" for j in idx))
        if joint_rad is not None:
            lines.append("deg    " + "".join(f"{np.degrees(joint_rad[j]):>{col}.3f}" for j in idx))
        if counts is not None:
            lines.append("counts " + "".join(f"{int(counts[j]):>{col}d}" for j in idx))
    return lines


def point_lines(points: dict[str, np.ndarray]) -> list[str]:
    return [f"point {name}: x {p[0]:.3f}  y {p[1]:.3f}  z {p[2]:.3f} mm" for name, p in points.items()]


#: weight of the newest step time in a kind's smoothed step time, and of the newest projection in the finish time
STEP_SMOOTHING = 0.3
FINISH_SMOOTHING = 0.3


@dataclass
class Progress:
    """Steps per procedure, done and total, and a steady estimate of the time left.

    Why per kind of step and smoothed: the steps of one session differ by a factor of ten (a coupling step is an
    encoder window, a compliance step is hanging weights), so the median of every step times the steps left jumped
    110 -> 50 -> 80 -> 42 min as the kinds alternated.  Each procedure keeps its own smoothed step time
    (exponential, :data:`STEP_SMOOTHING`); a procedure not timed yet counts at the median of those that are; and the
    projected finish time is smoothed again (:data:`FINISH_SMOOTHING`), so the time left counts down steadily
    between steps instead of following every step's surprise."""

    order: list[str] = field(default_factory=list)
    total: dict[str, int] = field(default_factory=dict)
    done: dict[str, int] = field(default_factory=dict)
    step_s: dict[str, float] = field(default_factory=dict)      # smoothed seconds a step takes, by procedure
    timed: int = 0
    finish_s: float | None = None                               # smoothed projected finish, on the caller's clock

    @classmethod
    def of(cls, procedures: list[str]) -> "Progress":
        p = cls()
        for name in procedures:
            if name not in p.total:
                p.order.append(name)
                p.total[name] = 0
                p.done[name] = 0
            p.total[name] += 1
        return p

    def mark_done(self, procedure: str, seconds: float | None = None, now_s: float | None = None) -> None:
        """A step of ``procedure`` is done; it took ``seconds`` (None: not timed, e.g. saved in an earlier run).
        ``now_s``: the caller's clock, to project the finish."""
        if procedure in self.done:
            self.done[procedure] = min(self.done[procedure] + 1, self.total[procedure])
        if seconds is not None and seconds >= 0 and procedure in self.done:
            prev = self.step_s.get(procedure)
            self.step_s[procedure] = seconds if prev is None else prev + STEP_SMOOTHING * (seconds - prev)
            self.timed += 1
        if now_s is not None:
            est = self.estimate_s()
            if est is not None:
                finish = now_s + est
                self.finish_s = finish if self.finish_s is None else \
                    self.finish_s + FINISH_SMOOTHING * (finish - self.finish_s)

    @property
    def steps_done(self) -> int:
        return sum(self.done.values())

    @property
    def steps_total(self) -> int:
        return sum(self.total.values())

    def estimate_s(self) -> float | None:
        """Steps left of each procedure times its smoothed step time; ``None`` until two steps were timed."""
        if self.timed < 2:
            return None
        default = float(np.median(list(self.step_s.values())))
        return float(sum((self.total[p] - self.done[p]) * self.step_s.get(p, default) for p in self.order))

    def remaining_s(self, now_s: float | None = None) -> float | None:
        """The time left: to the smoothed finish when the caller's clock is given, else the raw estimate."""
        if self.steps_done >= self.steps_total:
            return 0.0 if self.timed >= 2 else None
        if now_s is None or self.finish_s is None:
            return self.estimate_s()
        return max(self.finish_s - now_s, 0.0)

    def group_label(self, procedure: str) -> str:
        return f"{procedure}  {self.done.get(procedure, 0)}/{self.total.get(procedure, 0)}"

    def header(self, current: str | None, now_s: float | None = None, width: int | None = None) -> str:
        """``12/176 steps · sweep 3/30 · about 14 min left``; within ``width`` characters the current procedure's
        count goes first (the plan shows it too), the time left and the step count stay."""
        parts = [f"{self.steps_done}/{self.steps_total} steps"]
        left = self.remaining_s(now_s)
        if left is not None and self.steps_done < self.steps_total:
            parts.append(f"about {duration_text(left)} left")
        if current in self.total:
            with_current = parts[:1] + [f"{current} {self.done[current]}/{self.total[current]}"] + parts[1:]
            if width is None or len(" · ".join(with_current)) <= width:
                parts = with_current
        return " · ".join(parts)


def duration_text(seconds: float) -> str:
    """A time left as an operator reads it, rounded to what an estimate knows: ``40 s``, ``14 min``, ``1 h 50 min``
    (to 5 min above half an hour)."""
    if seconds < 90:
        return f"{max(10, round(seconds / 10) * 10):.0f} s"
    minutes = seconds / 60
    if minutes < 30:
        return f"{minutes:.0f} min"
    minutes = 5 * round(minutes / 5)
    return f"{minutes} min" if minutes < 60 else f"{minutes // 60} h {minutes % 60:02d} min"


#: columns whose values are named in a stacked row (a bare second number would read as the first's repeat)
LABELLED = ("limit", "1 sigma", "truth")


def table_of(columns: list[str], rows: list[tuple], stacked: bool = False):
    """A Rich table as wide as its panel whose last column (a check's reason) wraps instead of being cut, so the
    panel takes the height the rows need.  ``stacked`` (narrow terminals): two columns, the first one's and the rest
    run together as one wrapped text, ``name · value · limit · reason``."""
    from rich import box
    from rich.table import Table

    t = Table(expand=True, box=box.SIMPLE_HEAD, pad_edge=False, padding=(0, 1), show_edge=False,
              show_header=not stacked)
    if stacked:
        first = 1 if columns[:2] == ["check", "result"] else 0      # a check: its verdict leads the row
        t.add_column(columns[first], no_wrap=True)
        t.add_column(" · ".join(c for i, c in enumerate(columns) if i != first), ratio=1, overflow="fold")
        for r in rows:
            t.add_row(r[first], " · ".join(f"{columns[i]} {v}" if columns[i] in LABELLED else str(v)
                                           for i, v in enumerate(r) if i != first and str(v)))
        return t
    for i, name in enumerate(columns):
        last = i == len(columns) - 1
        t.add_column(name, ratio=1 if last else None, overflow="fold", no_wrap=not last,
                     justify="left" if i == 0 or last else "right")
    for r in rows:
        t.add_row(*r)
    return t


def check_row(d: dict) -> tuple[str, str, str, str, str]:
    """One check as the table shows it: name, pass/FAIL, value and limit with their unit, the reason in full."""
    unit = d.get("unit") or ""
    val, lim = d.get("value"), d.get("limit")
    return (d.get("name", ""), "[green]pass[/]" if d.get("passed") else "[b red]FAIL[/]",
            "" if val is None else f"{val:.4g} {unit}".rstrip(), "" if lim is None else f"{lim:.4g} {unit}".rstrip(),
            d.get("message", ""))
