"""Start-up (issue 18, item 2): each command imports its own code only when it runs, and no path imports a heavy
library it does not use (scipy.stats is never needed; scipy.optimize only by the set-up search and by a fit its
Gauss-Newton steps cannot finish).

These check which modules are loaded, in fresh processes; the times are in ``benchmarks/bench_startup.py``.
"""
from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from app import cli
from app import commands

ROOT = Path(__file__).resolve().parents[1]
#: libraries no command module may import when it is loaded (its run may, where it needs them)
HEAVY = ("scipy", "matplotlib", "textual", "rich", "cantools", "can", "serial", "jsonschema", "yourdfpy", "jinja2",
         "yaml", "pinocchio")

_AFTER = ("import contextlib, io, json, sys\n"
          "from app.cli import main\n"
          "rcs = []\n"
          "with contextlib.redirect_stdout(io.StringIO()):\n"
          "    for argv in %r:\n"
          "        rcs.append(main(argv))\n"
          "print(json.dumps({'rc': rcs, 'modules': sorted(m for m in sys.modules if m.split('.')[0] in %r)}))\n")


def _loaded_after(argvs: list[list[str]]) -> set[str]:
    """The heavy modules loaded in a fresh process after running the commands ``argvs`` in turn."""
    code = _AFTER % (argvs, HEAVY)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["rc"] == [0] * len(argvs), (out["rc"], r.stderr)
    return set(out["modules"])


def _full_parse(path: str) -> dict[str, str]:
    tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    return {n.targets[0].id: ast.literal_eval(n.value) for n in tree.body
            if isinstance(n, ast.Assign) and len(n.targets) == 1 and isinstance(n.targets[0], ast.Name)
            and n.targets[0].id in ("NAME", "HELP", "DESCRIPTION", "EXAMPLES")}


def test_the_index_read_from_the_files_heads_is_the_whole_files():
    """``--help`` parses only the head of each command file; it must find what a whole parse finds."""
    folder = commands.__path__[0]
    files = sorted(f for f in os.listdir(folder) if f.endswith(".py") and not f.startswith("_"))
    whole = {c["NAME"]: (c["HELP"], c.get("DESCRIPTION", c["HELP"]), c.get("EXAMPLES", ""))
             for c in (_full_parse(os.path.join(folder, f)) for f in files) if "NAME" in c}
    index = cli.command_index()
    assert {name: (h, d, e) for name, (_, h, d, e) in index.items()} == whole
    assert len(index) >= 15


def test_a_constant_below_the_first_function_is_still_found(tmp_path):
    src = tmp_path / "late.py"
    src.write_text('"""doc"""\ndef add_arguments(p):\n    pass\n\n\nNAME = "late"\nHELP = ("h" "elp")\n')
    assert cli._constants(str(src)) == {"NAME": "late", "HELP": "help"}


def test_no_command_module_imports_a_heavy_library_when_loaded():
    code = ("import importlib, json, os, sys\n"
            "from app import commands\n"
            "folder = commands.__path__[0]\n"
            "out = {}\n"
            "for f in sorted(os.listdir(folder)):\n"
            "    if f.endswith('.py') and f != '__init__.py':\n"
            "        importlib.import_module('app.commands.' + f[:-3])\n"
            "        out[f] = sorted(m for m in sys.modules if m.split('.')[0] in %r)\n"
            "print(json.dumps(out))\n") % (HEAVY,)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    loaded = json.loads(r.stdout)
    assert len(loaded) >= 15 and not any(loaded.values()), {f: m for f, m in loaded.items() if m}


def test_light_commands_run_without_scipy():
    loaded = _loaded_after([["fk", "0", "-90", "90", "0", "0", "0"], ["plan", "poses", "--count", "12"]])
    assert not any(m.startswith("scipy") for m in loaded), loaded


def test_fits_never_load_scipy_stats(tmp_path):
    """A plain fit loads no scipy at all (Gauss-Newton, the tests' tails and the thread cap are robocal's own); a
    fit with a loss only scipy's trust region minimises loads scipy.optimize, never scipy.stats."""
    csv = str(tmp_path / "twin.csv")
    loaded = _loaded_after([["twin", "--poses", "60", "--seed", "1", "--export", csv], ["identify", csv]])
    assert not any(m.startswith("scipy") for m in loaded), sorted(loaded)
    loaded = _loaded_after([["identify", csv, "--loss", "huber"]])
    assert "scipy" in loaded                    # the check sees what is loaded (the trust region's scipy.optimize)
    assert not any(m.startswith("scipy.stats") for m in loaded), sorted(loaded)


@pytest.mark.skipif(not (ROOT / "examples" / "demo-session.db").exists(), reason="no example session")
def test_reprocess_loads_no_scipy_stats(tmp_path):
    db = tmp_path / "demo-session.db"
    shutil.copy(ROOT / "examples" / "demo-session.db", db)
    loaded = _loaded_after([["reprocess", str(db), "--json", str(tmp_path / "r.json")]])
    assert not any(m.startswith("scipy.stats") for m in loaded), sorted(loaded)
