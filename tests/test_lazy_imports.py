"""An import inside a function only where start-up time or an import circle needs it, and then saying which (issue
25, item 6): every ``import`` inside a function of the library packages (not the application shell ``app/``, whose
commands import their own code when they run) has a comment on its own line or the line above, e.g.
``# scipy.linalg costs ~0.3 s at start-up (robocal plan loads this module and fits nothing)``.  A run of imports
directly under one comment counts as commented.  Anything cheap and free of circles belongs at the module's top.

Which modules each command path loads is checked in ``test_cli_startup.py``; the times are in
``benchmarks/bench_startup.py``.
"""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("acq", "calib", "offline", "sim")


def uncommented(source: str) -> list[tuple[int, str]]:
    """(line, statement) of each import inside a function with no comment on its line, on the line above, or above
    the run of imports it stands in."""
    lines = source.splitlines()
    found: list[tuple[int, str]] = []

    def commented(node: ast.stmt) -> bool:
        if "#" in lines[node.lineno - 1]:
            return True
        i = node.lineno - 2                      # the line above, climbing over a run of imports
        while i >= 0:
            above = lines[i].strip()
            if above.startswith("#"):
                return True
            if not above.startswith(("import ", "from ")):
                return False
            i -= 1
        return False

    def walk(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if in_function and isinstance(child, (ast.Import, ast.ImportFrom)) and not commented(child):
                found.append((child.lineno, lines[child.lineno - 1].strip()))
            walk(child, in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    walk(ast.parse(source), False)
    return found


def test_the_check_finds_an_uncommented_import_in_a_function():
    src = ("import os\n\n"
           "def f():\n    import json\n    return json\n\n"
           "def g():\n    # scipy is slow to import\n    import scipy\n    import scipy.linalg\n\n"
           "def h():\n    import numpy  # lazy: start-up\n\n"
           "class C:\n    def m(self):\n        def inner():\n            from . import x\n        return inner\n")
    assert uncommented(src) == [(4, "import json"), (18, "from . import x")]


def test_every_in_function_import_of_the_library_says_why():
    missing = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            for line, stmt in uncommented(path.read_text(encoding="utf-8")):
                missing.append(f"{rel}:{line}: {stmt}")
    assert not missing, ("imports inside functions with no comment saying why (start-up time, an import circle); "
                         "move them to the module's top or comment them:\n" + "\n".join(missing))
