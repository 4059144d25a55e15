"""ISO 9283 AP and RP worked by hand from the rows of a session, with nothing of robocal: plain Python sums and the
statistics module (ISO 9283 §7.2.1: AP is the distance from the commanded position to the barycentre of the attained
ones; §7.2.2: RP = l̄ + 3 S_l, l_j the distance of attempt j from the barycentre, S_l their sample deviation)."""
from __future__ import annotations

import math
import statistics


def ap_rp(command_mm, attained_mm) -> tuple[float, float]:
    """(AP, RP) in mm of one pose."""
    n = len(attained_mm)
    bary = [sum(p[i] for p in attained_mm) / n for i in range(3)]
    ap = math.sqrt(sum((bary[i] - command_mm[i]) ** 2 for i in range(3)))
    dist = [math.sqrt(sum((p[i] - bary[i]) ** 2 for i in range(3))) for p in attained_mm]
    return ap, statistics.mean(dist) + 3.0 * statistics.stdev(dist)


def figures(rows: list[dict]) -> dict[tuple[str, str], tuple[float, float, int]]:
    """(run, pose) -> (AP, RP, n) from rows ``{"run", "pose", "command_mm", "attained_mm"}``."""
    groups: dict[tuple[str, str], tuple[list, list]] = {}
    for r in rows:
        groups.setdefault((r["run"], r["pose"]), (r["command_mm"], []))[1].append(r["attained_mm"])
    return {k: (*ap_rp(c, pts), len(pts)) for k, (c, pts) in groups.items()}
