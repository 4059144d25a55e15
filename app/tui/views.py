"""What the TUI derives from the recorded events, without touching a device: intersected points per step, the
series each procedure's plot shows, and small set-up diagrams.  Pure functions and plain data, testable alone."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from acq.session.checks import intersect_targets
from calib.errors import RobocalError
from calib.estimators.transmission import joint_angle
from calib.theodolite import Station
from calib.units import DEG

DIAGRAMS = {
    "ruler": """\
  C ─────── D ─────────────── E    ruler, marks level with the
   ╲       │               ╱       theodolites' optical centres
    ╲      │             ╱
     A ═══════ L ══════ B          sight C, D, E from A, then B""",
    "sweep": """\
        ╭──── P ────╮              target P on link j
       │     ·      │  R_j         turn joint j only
        ╰─── axis ──╯              sight P from A and B
     A ═══════ L ══════ B          at every position""",
    "transmission": """\
     A1 ●━━━━━━━━━━● A2            extended tool, targets R_dj apart
            │ axis j               turn joint j slowly, one way
     A ═══════ L ══════ B          sight A1 and A2 at every stop""",
    "compliance": """\
     joint j ●━━━━━━━━┓  L_j       hang the load N_j at L_j
                      ▼ N          load up, then unload
     A ═══════ L ══════ B          sight the target after each load""",
    "link_compliance": """\
     ┣━━━━━━━━━━━━━━━━━┓           link j as a cantilever
       ▲g1   ▲g2   ▲g3 ▼ N         read every dial gauge
                                   after each load""",
    "coupling": """\
     joint j ↻   joint k ↻          move j alone, then j with k
     tap encoders of j and k        the tap records both""",
    "poses": """\
        ╭─╮ robot pose q           move to the pose
        │ ● tool target            sight the tool target
     A ═══════ L ══════ B          from A and B""",
}


@dataclass
class StepData:
    """Everything recorded for one step attempt, from the events."""

    key: str
    procedure: str
    meta: dict = field(default_factory=dict)
    readings: list = field(default_factory=list)       # (station, target, face, hz_rad, v_rad)
    joint_deg: list | None = None
    inputs: dict = field(default_factory=dict)
    checks: list = field(default_factory=list)
    status: str = ""
    _cache: tuple = field(default=(None, {}), repr=False)

    def points(self, stations: dict[str, Station]) -> dict[str, np.ndarray]:
        """Intersected point per target, as the session's checks compute it (face mean, then intersection); cached
        until a new reading arrives, because the live panel asks ten times a second."""
        key = (len(self.readings), id(stations))
        if self._cache[0] != key:
            rows = [{"station": st, "target": tg, "face": f, "hz_rad": h, "v_rad": v}
                    for st, tg, f, h, v in self.readings]
            try:
                pts = ({k: v[0] for k, v in intersect_targets(rows, stations).items()}
                       if len(stations) >= 2 else {})
            except RobocalError:
                pts = {}
            self._cache = (key, pts)
        return self._cache[1]


Series = tuple[str, str, str, list]          # (title, x label, y label, [(label, xs, ys)])
PlotFn = Callable[[list[StepData], dict[str, Station]], "Series | None"]
#: the live plot of each procedure, by procedure name (a procedure without one gets the miss-distance plot)
PLOTS: dict[str, PlotFn] = {}


def plot_for(*procedures: str):
    """Register the live plot of one or more procedures."""
    def register(fn: PlotFn) -> PlotFn:
        for name in procedures:
            PLOTS[name] = fn
        return fn
    return register


def plot_series(procedure: str, steps: list[StepData], stations: dict[str, Station]) -> Series | None:
    """(title, x label, y label, [(label, xs, ys)]) for the current procedure's plot, or None if too little data."""
    return PLOTS.get(procedure, miss_distance_plot)(steps, stations)


@plot_for("sweep", "sweeps")
def circle_residuals_plot(steps: list[StepData], stations: dict[str, Station]) -> Series | None:
    """Radial and out-of-plane residuals of the circle the swept target describes."""
    P = [next(iter(s.points(stations).values())) for s in steps if s.points(stations)]
    if len(P) < 4:
        return None
    from calib.estimators.axes import fit_circle
    P = np.array(P)
    th = fit_circle(P)
    c, n, r = th[:3], th[3:6], th[6]
    d = P - c
    radial = np.linalg.norm(d - np.outer(d @ n, n), axis=1) - r
    return ("circle fit residuals", "position", "mm",
            [("radial", list(range(1, len(P) + 1)), radial.tolist()),
             ("out of plane", list(range(1, len(P) + 1)), (d @ n).tolist())])


@plot_for("transmission")
def transmission_error_plot(steps: list[StepData], stations: dict[str, Station]) -> Series | None:
    """Joint angle from the two targets minus the encoder's, over the encoder angle."""
    pairs = [(s.points(stations), s.joint_deg, s.meta.get("joint")) for s in steps]
    pairs = [(p, q, j) for p, q, j in pairs if len(p) >= 2 and q is not None and j]
    if len(pairs) < 4:
        return None
    names = sorted(pairs[0][0])
    A1 = np.array([p[names[0]] for p, _, _ in pairs])
    A2 = np.array([p[names[1]] for p, _, _ in pairs])
    n = np.linalg.svd(A1 - A1.mean(0))[2][-1]                 # axis: normal of the plane A1 sweeps
    x = np.concatenate([np.broadcast_to(A1[0], A1.shape), np.broadcast_to(A2[0], A2.shape), A1, A2], axis=1)
    ang = np.unwrap(joint_angle(x, n)[:, 0])                  # eq 4.4.1, the estimator's own function
    j = int(pairs[0][2]) - 1
    enc = np.array([q[j] for _, q, _ in pairs]) * DEG
    sgn = np.sign(np.polyfit(enc - enc[0], ang, 1)[0]) or 1.0
    err = sgn * ang - (enc - enc[0])
    return ("transmission error", f"joint {j + 1} encoder (deg)", "deg",
            [("measured - encoder", (enc / DEG).tolist(), ((err - err.mean()) / DEG).tolist())])


@plot_for("compliance")
def deflection_plot(steps: list[StepData], stations: dict[str, Station]) -> Series | None:
    """Deflection of the first target against the load entered, loading and unloading apart."""
    rows = []
    first = None
    unit = "N"
    for s in steps:
        p = s.points(stations)
        if not p:
            continue
        pt = next(iter(p.values()))
        first = pt if first is None else first
        key = next((k for k in s.inputs if k.startswith("load_")), None)
        load = s.inputs[key] if key is not None else s.meta.get("load_n")
        if load is None:
            continue
        unit = key.split("_", 1)[1] if key is not None else unit
        unloading = str(s.meta.get("phase", "")).startswith("unload")
        rows.append((float(load), float(np.linalg.norm(pt - first)), "unloading" if unloading else "loading"))
    if len(rows) < 3:
        return None
    series = [(phase, [r[0] for r in rows if r[2] == phase], [r[1] for r in rows if r[2] == phase])
              for phase in ("loading", "unloading") if any(r[2] == phase for r in rows)]
    return ("deflection under load", f"load ({unit})", "mm", series)


def miss_distance_plot(steps: list[StepData], stations: dict[str, Station]) -> Series | None:
    """Miss distance of the sight lines, sighting after sighting (any procedure with sightings)."""
    miss = []
    for s in steps:
        for c in s.checks:
            if c.get("name", "").startswith("miss") and c.get("value") is not None:
                miss.append(float(c["value"]))
    if len(miss) < 2:
        return None
    return ("miss distance of the sight lines", "sighting", "mm", [("miss", list(range(1, len(miss) + 1)), miss)])
