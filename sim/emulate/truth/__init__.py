"""The emulated truth of a reduced session, scored after the reduction: the simulation side's, never the reduction's.

An emulated session records its twin (scenario and seed) in its metadata; :func:`score` rebuilds that twin and fills
each estimate's ``truth`` -- what a perfect estimator would return from these very steps -- from the reduction's
results document and its ``trace`` (what each stage computed its estimates from: the joint readings of the pose set,
the torques of a loading series ...).  Where the twin's own value is not what the estimator estimates (a gauge held
by the fit, a single slope over two, eq 4.3.15's reading of tilted axes), the truth is the twin's value carried into
the estimator's terms by formulas written out here (exact gauge rules of the chain, a weighted line, the thesis's
section 4.3.1 in :mod:`.scheme`) -- never the reduction's estimators run on the twin's noise-free data -- and the
twin's own value is kept as ``truth_raw`` with a note.  One module per group of stages registers its truth functions
by stage name (:data:`TRUTHS`).
"""
from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module
from typing import Callable

from calib.provenance import file_sha256
from calib.robot import Robot
from sim.twin import Twin, load_scenario, parse_scenario

from offline.reduction.session import SessionData, load_session
from acq.session.setup import setup_robot
from acq.session.setup_types import BenchSetup

#: stage name -> truth function(scoring, trace of the stage)
TRUTHS: dict[str, Callable[["Scoring", dict], None]] = {}
MODULES = ("geometry", "runs", "poses")


def truth_of(stage: str):
    """Register a stage's truth function."""
    def register(fn):
        TRUTHS[stage] = fn
        return fn
    return register


@dataclass
class Scoring:
    """A results document being scored against its twin."""

    twin: Twin
    res: dict
    data: SessionData
    robot: Robot

    @property
    def setup(self) -> BenchSetup:
        return self.data.setup

    @property
    def truth(self) -> dict[str, float]:
        return self.twin.true_parameters()

    def estimate(self, name: str) -> dict | None:
        return next((e for e in self.res["estimates"] if e["name"] == name), None)

    def set(self, name: str, truth: float | None, raw: float | None = None, note: str | None = None) -> None:
        """The truth of estimate ``name`` (absent estimates are skipped); ``raw``: the twin's own value where the
        truth is not it, with ``note`` saying why."""
        e = self.estimate(name)
        if e is None:
            return
        if truth is not None:
            e["truth"] = float(truth)
        if raw is not None:
            e["truth_raw"] = float(raw)
        if note:
            e["note"] = "; ".join(filter(None, [e.get("note"), note]))

    def set_bound(self, name: str, truth: float | None, note: str | None = None) -> None:
        for b in self.res["bounds"]:
            if b["name"] == name:
                b["truth"] = None if truth is None else float(truth)
                if note:
                    b["truth_note"] = note


def session_twin(data: SessionData) -> Twin | None:
    """The twin an emulated session was recorded with (its scenario -- a file, its text, or the default -- and seed);
    None for a session from real instruments."""
    meta = data.metadata
    if not meta.get("emulated"):
        return None
    if meta.get("scenario_toml"):
        scenario = parse_scenario(meta["scenario_toml"], meta.get("scenario_path") or f"{data.path}: scenario")
    else:
        scenario = load_scenario(meta.get("scenario_path") or None)
    return Twin(scenario, seed=meta.get("seed", 0))


def _imported() -> None:
    for m in MODULES:
        import_module(f"{__name__}.{m}")


#: what :func:`prepare` made, by the session's path and metadata: (twin, set-up, its robot)
_PREPARED: dict[tuple[str, str], tuple[Twin, BenchSetup, Robot]] = {}


def prepare(data: SessionData) -> None:
    """What scoring an emulated session needs besides its results, made now: the truth modules imported, its twin
    and robot built (about 30 ms).  Why: a reduction while the session records (:mod:`app.live_reduction`) makes it
    while it waits for steps, not after the session's last one.  :func:`score` takes them once, for the same session
    (path, metadata and set-up); a session from real instruments needs none."""
    twin = session_twin(data)
    if twin is not None:
        _imported()
        _PREPARED[(data.path, data.session.get("metadata_json") or "")] = (twin, data.setup, setup_robot(data.setup))


def score(res: dict, data: SessionData | str) -> dict:
    """``res`` (from :func:`offline.reduction.run.reduce_session`) with the emulated truths filled in, when the session
    was recorded from emulated instruments; unchanged otherwise."""
    data = load_session(data) if isinstance(data, str) else data
    made = _PREPARED.pop((data.path, data.session.get("metadata_json") or ""), None)
    if made is not None and made[1] == data.setup:      # the twin as new: built for this one scoring, unused
        twin, robot = made[0], made[2]
    else:
        twin = session_twin(data)
        if twin is None:
            return res
        robot = setup_robot(data.setup)
    _imported()
    sc = Scoring(twin, res, data, robot)
    trace = res.get("trace") or {}
    for stage, fn in TRUTHS.items():
        fn(sc, trace.get(stage) or {})
    res["provenance"]["scenario_sha256"] = file_sha256(twin.scenario.source, "twin_default.toml")
    return res
