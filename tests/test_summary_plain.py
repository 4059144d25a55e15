"""The terminal summary printed where no styles show (a pipe, a file, a log): the same bytes rich prints there, without
importing rich (0.05-0.08 s of every ``robocal demo`` and ``reprocess`` whose output is not a terminal)."""
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from rich.console import Console

from offline.summary import styled_stdout, summary_lines, unstyled

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "examples" / "demo-session.json"

TRICKY = ["plain σ ± text, 0.102 mm (95 % 0.179)", "a\tb\tc", "joint 4:\ttab after a colon", "two\nlines\twith tab",
          "note: x:ok:y and :smile: stay text", "bell\x07 back\x08 cr\r vt\x0b ff\x0c esc\x1b[31m kept", "trail   ",
          "", " lead", "a" * 200, "\x00nul \x7f del \x85 nel"]


def rich_unstyled(text: str, style: str | None = "bold green") -> str:
    """What :func:`offline.summary.print_summary`'s rich console writes for one line when it is not a terminal."""
    buf = io.StringIO()
    Console(file=buf, _environ={}).print(text, style=style, highlight=False, markup=False, soft_wrap=True,
                                         emoji=False)
    return buf.getvalue()


@pytest.mark.parametrize("text", TRICKY)
def test_unstyled_is_what_rich_prints_without_styles(text):
    assert unstyled(text) + "\n" == rich_unstyled(text)
    assert unstyled(text) + "\n" == rich_unstyled(text, None)


class _Stream(io.StringIO):
    def __init__(self, tty: bool):
        super().__init__()
        self.tty = tty

    def isatty(self) -> bool:
        return self.tty


@pytest.mark.parametrize("tty", [False, True])
@pytest.mark.parametrize("env", [{}, {"FORCE_COLOR": "1"}, {"FORCE_COLOR": ""}, {"TTY_COMPATIBLE": "1"},
                                 {"TTY_COMPATIBLE": "0", "FORCE_COLOR": "1"}, {"TTY_COMPATIBLE": "2"},
                                 {"NO_COLOR": "1"}])
def test_styled_stdout_answers_as_rich(monkeypatch, env, tty):
    stream = _Stream(tty)
    monkeypatch.setattr(sys, "stdout", stream)
    assert styled_stdout(env) == Console(file=stream, _environ=env).is_terminal


def test_the_summary_piped_is_richs_without_rich():
    """A whole summary (the example session's results) printed to a pipe: the lines rich prints, and rich never
    loaded."""
    res = json.loads(RESULTS.read_text(encoding="utf-8"))
    expected = "".join(rich_unstyled(text, style or None) for style, text in summary_lines(res))
    code = ("import json, sys\nfrom offline.summary import print_summary\n"
            f"print_summary(json.loads(open({str(RESULTS)!r}, encoding='utf-8').read()))\n"
            "print('rich loaded' if 'rich' in sys.modules else 'no rich', file=sys.stderr)\n")
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "TTY_COMPATIBLE")}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env["PYTHONIOENCODING"] = "utf-8"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, encoding="utf-8", env=env,
                       cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert r.stderr.strip() == "no rich"
    assert len(expected) > 500 and r.stdout == expected
