"""Running validation cases in worker processes: one implementation for the twin suite and the independent families.

Why a module of its own: both suites map a case function over many cases, report progress, and want one BLAS thread
per worker (the workers are the parallelism; spawned processes read the setting when they start)."""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Sequence, TypeVar

from calib.threads import FITS_ENV, blas_environment, variables

C = TypeVar("C")
R = TypeVar("R")


def map_cases(fn: Callable[[C], R], cases: Sequence[C], workers: int | None = None, progress=None) -> list[R]:
    """``[fn(c) for c in cases]`` in ``workers`` spawned processes (default: the CPU count; 1: in this process),
    calling ``progress("validation", share_done)`` after each case."""
    workers = workers or min(len(cases), os.cpu_count() or 1)
    results: list[R] = []

    def done(r: R) -> None:
        results.append(r)
        if progress:
            progress("validation", len(results) / len(cases))

    if workers <= 1:
        for c in cases:
            done(fn(c))
        return results
    # the variables stay set while the pool runs: it spawns its workers at the first submit, not when it is built
    # ... and one fit at a time inside each worker: the workers fill the cores already
    with blas_environment(1), variables({FITS_ENV: "1"}), \
            ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as ex:
        for r in ex.map(fn, cases, chunksize=1):
            done(r)
    return results
