"""The ``robocal`` command runs BLAS on one thread unless the user asks for more (issue 18, item 1).

The count must be fixed before numpy loads (BLAS libraries read it once), so the checks run the command in a fresh
process, through the two ways it is started (the console script's ``from app.cli import main`` and
``python -m app.cli``), and read the loaded BLAS's own thread count with threadpoolctl after the command ran.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from calib import threads

#: after the command (fk: loads numpy and the model), report the BLAS threads and the variables as JSON
_REPORT = ("import json, os\n"
           "from threadpoolctl import threadpool_info\n"
           "print(json.dumps({'rc': rc, 'blas': [p['num_threads'] for p in threadpool_info() "
           "if p['user_api'] == 'blas'], 'env': {k: os.environ.get(k) for k in %r}}))\n" % (threads.BLAS_ENV_VARS,))
_CONSOLE = ("import sys, contextlib, io\n"
            "sys.argv = ['robocal'] + %r\n"
            "from app.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    rc = main()\n") + _REPORT
_MODULE = ("import sys, contextlib, io, runpy\n"
           "sys.argv = ['robocal'] + %r\n"
           "with contextlib.redirect_stdout(io.StringIO()):\n"
           "    try:\n"
           "        runpy.run_module('app.cli', run_name='__main__', alter_sys=True)\n"
           "    except SystemExit as exc:\n"
           "        rc = exc.code\n") + _REPORT
_FK = ["fk", "0", "-90", "90", "0", "0", "0"]
_TWO_CORES = pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="more than one BLAS thread needs two cores")


def _clean_env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in threads.BLAS_ENV_VARS + (threads.THREADS_ENV,)}
    env.update(extra)
    return env


def _run(template: str, argv: list[str], **extra: str) -> dict:
    r = subprocess.run([sys.executable, "-c", template % (argv,)], capture_output=True, text=True, timeout=120,
                       env=_clean_env(**extra))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["rc"] == 0 and out["blas"], out
    return out


@pytest.mark.parametrize("template", [_CONSOLE, _MODULE], ids=["console-script", "python-m"])
def test_the_command_runs_blas_on_one_thread_by_default(template):
    out = _run(template, _FK)
    assert set(out["blas"]) == {1}
    assert all(v == "1" for v in out["env"].values()), out["env"]      # children (workers, emulators) inherit it


@_TWO_CORES
def test_without_robocal_blas_would_be_threaded():
    """The check above can fail: the same interpreter without the command's setting runs BLAS threaded."""
    code = ("import json, numpy\nfrom threadpoolctl import threadpool_info\n"
            "print(json.dumps([p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=_clean_env())
    assert max(json.loads(r.stdout)) > 1


@_TWO_CORES
@pytest.mark.parametrize("argv, extra", [
    (["--threads", "2"] + _FK, {}),
    (_FK + ["--threads=2"], {}),                                        # anywhere on the line, like --debug
    (_FK, {threads.THREADS_ENV: "2"}),
    (["--threads", "2"] + _FK, {threads.THREADS_ENV: "1", "OMP_NUM_THREADS": "1"}),   # the option wins
])
def test_more_threads_on_request(argv, extra):
    out = _run(_CONSOLE, argv, **extra)
    assert set(out["blas"]) == {2}
    assert all(v == "2" for v in out["env"].values()), out["env"]


@_TWO_CORES
@pytest.mark.parametrize("var", ["OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"])
def test_a_users_own_blas_setting_is_respected(var):
    out = _run(_CONSOLE, _FK, **{var: "2"})
    assert set(out["blas"]) == {2}
    assert {k: v for k, v in out["env"].items() if v is not None} == {var: "2"}     # nothing else set


def test_the_entry_module_imports_no_numpy():
    """``--threads`` acts before numpy loads only if nothing on the way to main() imports it."""
    code = "import sys, app.cli\nassert not [m for m in ('numpy', 'scipy') if m in sys.modules]"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("argv, extra, where", [
    (["--threads", "0"] + _FK, {}, "--threads"), (["--threads", "x"] + _FK, {}, "--threads"),
    (_FK + ["--threads"], {}, "--threads"), (_FK, {threads.THREADS_ENV: "many"}, threads.THREADS_ENV),
])
def test_bad_thread_counts_are_one_line(argv, extra, where):
    r = subprocess.run([sys.executable, "-m", "app.cli", *argv], capture_output=True, text=True, timeout=60,
                       env=_clean_env(**extra))
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith(f"robocal: error: {where} must be")


def test_configure_fills_only_what_the_user_left_unset():
    env = {}
    assert threads.configure(None, env) == 1 and env == {k: "1" for k in threads.BLAS_ENV_VARS}
    env = {"MKL_NUM_THREADS": "4"}
    assert threads.configure(None, env) is None and env == {"MKL_NUM_THREADS": "4"}
    env = {"MKL_NUM_THREADS": "4", threads.THREADS_ENV: "3"}
    assert threads.configure(None, env) == 3 and all(env[k] == "3" for k in threads.BLAS_ENV_VARS)
    env = {threads.THREADS_ENV: "3"}
    assert threads.configure(2, env) == 2 and all(env[k] == "2" for k in threads.BLAS_ENV_VARS)


def test_called_from_python_with_numpy_loaded_the_run_is_capped(monkeypatch):
    """In a process where numpy is already loaded the variables come too late: the run is capped instead, and the
    caller's environment is left as it was."""
    import numpy  # noqa: F401 -- loaded, as in a notebook or a test
    from threadpoolctl import threadpool_info

    from app import cli
    for k in threads.BLAS_ENV_VARS + (threads.THREADS_ENV,):
        monkeypatch.delenv(k, raising=False)
    def blas() -> dict[str, int]:
        return {p["filepath"]: p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}

    before = blas()
    with cli._blas_threads(None):
        assert set(blas().values()) == {1}
    after = blas()                       # the cap may have loaded scipy's own BLAS: it is restored to its default
    assert {k: after[k] for k in before} == before
    assert not any(k in os.environ for k in threads.BLAS_ENV_VARS)


@_TWO_CORES
def test_the_cap_covers_scipys_own_blas_loaded_during_the_run():
    """scipy brings its own OpenBLAS, which a command loads lazily after the cap began (threadpoolctl caps only what
    is loaded): in a fresh process with numpy loaded, every BLAS seen inside the cap runs one thread."""
    code = ("import json, numpy\nfrom threadpoolctl import threadpool_info\nfrom calib import threads\n"
            "with threads.limit(1):\n"
            "    import scipy.linalg\n"
            "    inside = [p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']\n"
            "print(json.dumps(inside))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=_clean_env())
    assert r.returncode == 0, r.stderr
    inside = json.loads(r.stdout.strip().splitlines()[-1])
    assert len(inside) >= 1 and set(inside) == {1}, inside
