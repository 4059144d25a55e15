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


@dataclass
class Progress:
    """Steps per procedure, done and total, and the time the finished steps took (for the estimate)."""

    order: list[str] = field(default_factory=list)
    total: dict[str, int] = field(default_factory=dict)
    done: dict[str, int] = field(default_factory=dict)
    durations_s: list[float] = field(default_factory=list)

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

    def mark_done(self, procedure: str, seconds: float | None = None) -> None:
        if procedure in self.done:
            self.done[procedure] = min(self.done[procedure] + 1, self.total[procedure])
        if seconds is not None and seconds >= 0:
            self.durations_s.append(seconds)

    @property
    def steps_done(self) -> int:
        return sum(self.done.values())

    @property
    def steps_total(self) -> int:
        return sum(self.total.values())

    def remaining_s(self) -> float | None:
        """Median time of the steps timed so far times the steps left; ``None`` until two steps were timed."""
        if len(self.durations_s) < 2:
            return None
        return float(np.median(self.durations_s)) * (self.steps_total - self.steps_done)

    def group_label(self, procedure: str) -> str:
        return f"{procedure}  {self.done.get(procedure, 0)}/{self.total.get(procedure, 0)}"

    def header(self, current: str | None) -> str:
        """Short enough for an 80-column header: ``12/176 steps · sweep 3/30 · ~14 min left``."""
        parts = [f"{self.steps_done}/{self.steps_total} steps"]
        if current in self.total:
            parts.append(f"{current} {self.done[current]}/{self.total[current]}")
        left = self.remaining_s()
        if left is not None:
            parts.append(f"~{left / 60:.0f} min left" if left >= 90 else f"~{left:.0f} s left")
        return " · ".join(parts)
