"""Offline reprocessing: the whole calibration rerun from a saved session with today's code, raw data read-only.

The composition the commands use: the reduction (:func:`offline.reduction.run.reduce_session`: every stage of the
stage registry, from the stored raw readings only) and then, for a session recorded from emulated instruments, the
emulated truth scored against its twin by the simulation side (:func:`sim.emulate.truth.score`) -- the reduction
itself never sees the twin.  The results document is the reduction's (see :mod:`offline.reduction.run`), without its
``trace``.
"""
from __future__ import annotations

from offline.reduction.run import reduce_session
from offline.reduction.session import SessionData, load_session

__all__ = ["reprocess", "scored", "load_session", "SessionData"]


def reprocess(path: str, n_mc: int = 0, progress=None) -> dict:
    """Rerun every stage of the session at ``path``; returns the results document."""
    data = load_session(path)
    return scored(reduce_session(data, n_mc=n_mc, progress=progress), data)


def scored(res: dict, data: SessionData) -> dict:
    """A reduction's results document as the commands show it: for a session recorded from emulated instruments,
    its truths scored against the twin; without the reduction's ``trace``."""
    if data.metadata.get("emulated"):
        from sim.emulate.truth import score         # the twin and its scenario: only for an emulated session
        score(res, data)
    res.pop("trace", None)
    return res
