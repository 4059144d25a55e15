"""How many threads the linear algebra (BLAS/LAPACK, OpenMP) may use: one, unless the user says otherwise.

Why one: robocal's matrices are a few thousand rows by tens of columns, where a threaded BLAS spends more time
waking and synchronising threads than computing (on the 2-core development machine a 900x33 SVD took 0.75 ms on one
thread and 5-10 ms threaded; a 400-pose ``robocal diagnose`` 1.7 s against 3.3 s).  BLAS libraries read their
thread count once, when they are loaded, so the ``robocal`` command sets these variables before anything imports
numpy (:func:`configure`); when numpy is already loaded (robocal called from Python), :func:`limit` caps the loaded
libraries for the duration of the call instead.

This module imports nothing heavy: it runs before numpy.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Iterator, MutableMapping
from contextlib import AbstractContextManager, contextmanager, nullcontext

#: the variables BLAS and OpenMP runtimes read for their thread count (OpenBLAS also reads OMP_NUM_THREADS)
BLAS_ENV_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                 "BLIS_NUM_THREADS")
#: robocal's own variable: the thread count for every BLAS (overrides the variables above), like ``--threads N``
THREADS_ENV = "ROBOCAL_THREADS"
DEFAULT_THREADS = 1


def parse_threads(raw: str, where: str) -> int:
    """A thread count >= 1 from ``raw``; a ValueError whose message reads after ``where`` otherwise."""
    try:
        value = int(str(raw).strip())
    except ValueError:
        value = 0
    if value < 1:
        raise ValueError(f"{where} must be a whole number of threads, at least 1, got {raw!r}")
    return value


def user_has_set(environ: MutableMapping[str, str] | None = None) -> bool:
    """Whether the user chose a thread count through any BLAS/OpenMP variable (then robocal leaves them all alone:
    setting OPENBLAS_NUM_THREADS would override a user's OMP_NUM_THREADS, which OpenBLAS reads after it)."""
    env = os.environ if environ is None else environ
    return any(env.get(k, "").strip() for k in BLAS_ENV_VARS)


def wanted(requested: int | None, environ: MutableMapping[str, str] | None = None) -> int | None:
    """The thread count to impose: ``requested`` (``--threads``), else ``ROBOCAL_THREADS``, else one thread unless
    the user set a BLAS variable (None: leave threading as the user set it)."""
    env = os.environ if environ is None else environ
    if requested is not None:
        return requested
    if env.get(THREADS_ENV, "").strip():
        return parse_threads(env[THREADS_ENV], THREADS_ENV)
    return None if user_has_set(env) else DEFAULT_THREADS


def configure(requested: int | None = None, environ: MutableMapping[str, str] | None = None) -> int | None:
    """Set the BLAS variables in ``environ`` (default: this process's, inherited by its children) to
    :func:`wanted`'s count; returns that count (None: the user's own setting stands).  Effective for this process
    only when numpy is not loaded yet."""
    env = os.environ if environ is None else environ
    n = wanted(requested, env)
    if n is not None:
        env.update({k: str(n) for k in BLAS_ENV_VARS})
    return n


def limit(n: int | None) -> AbstractContextManager:
    """A context capping the BLAS libraries at ``n`` threads for its duration (nothing for None or when numpy is not
    loaded: then :func:`configure`'s variables act when it loads).

    threadpoolctl caps only the libraries loaded when it starts, and scipy brings its own OpenBLAS, which a command
    may load lazily inside the context and which reads its thread count once, when it loads: so the BLAS variables
    are also set to ``n`` for the duration (and restored after), and a library loaded meanwhile keeps ``n`` threads.
    Importing scipy.linalg here instead (so that the cap covered it) cost 0.3 s of every diagnosis that needs no
    scipy at all."""
    if n is None or "numpy" not in sys.modules:
        return nullcontext()
    try:
        # optional (a speed-up only), and needed only once numpy is loaded: not on every start-up
        from threadpoolctl import threadpool_limits
    except ImportError:                         # a speed-up only
        return nullcontext()
    return _capped(n, threadpool_limits)


@contextmanager
def _capped(n: int, threadpool_limits) -> Iterator[None]:
    """The loaded libraries capped by threadpoolctl, and the variables set for those loaded meanwhile."""
    with blas_environment(n), threadpool_limits(n, user_api="blas"):
        yield


def blas_environment(n: int) -> AbstractContextManager:
    """This process's BLAS variables set to ``n`` for the duration, restored after (read by a BLAS library loaded
    meanwhile, and by child processes started meanwhile)."""
    return variables({k: str(n) for k in BLAS_ENV_VARS})


@contextmanager
def variables(values: dict[str, str]) -> Iterator[None]:
    """Environment variables set for the duration, restored after (child processes started meanwhile read them)."""
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


#: how many independent fits (a cross-validation's folds and its whole-set fit) run at once, in threads
FITS_ENV = "ROBOCAL_PARALLEL_FITS"
#: at most this many by default: the fits' Python share holds the interpreter's lock, so more threads than this only
#: wait (measured on 2 cores only)
MAX_PARALLEL_FITS = 4


def parallel_fits(environ: MutableMapping[str, str] | None = None) -> int:
    """Threads for independent fits: :data:`FITS_ENV` when set (1: one after the other), else the cores this process
    may use, at most :data:`MAX_PARALLEL_FITS`.  Why threads: each fit's model passes and factorisations are numpy
    and BLAS calls that release the interpreter's lock on a tree's thousands of rows (the elastic 19-joint tree's
    diagnosis 28-31 s -> 25 s wall on 2 cores, its JSON identical: every fit is the same computation, only when it
    runs changes); one BLAS thread each, as :func:`limit` sets.  Validation workers set it to 1 (their processes
    already fill the cores)."""
    env = os.environ if environ is None else environ
    raw = env.get(FITS_ENV)
    if raw:
        try:
            return parse_threads(raw, FITS_ENV)
        except ValueError:
            return 1
    return max(1, min(usable_cores(), MAX_PARALLEL_FITS))


def usable_cores() -> int:
    """The cores this process may run on (its affinity where the system says it, else the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:                      # not on Linux
        return os.cpu_count() or 1
