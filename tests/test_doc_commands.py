"""The documentation's examples run as written: every command in README.md and docs/*.md that names a shipped file
(a path under examples/ or calib/data/, or the bare name of such a file) is executed, and the figures the text quotes
for it are checked against its output.

How commands are found (generically, no list of them here):

* fenced code blocks: each line starting with ``robocal`` or ``python`` (a trailing ``  # comment`` is not part of
  it, a trailing backslash continues it);
* inline code spans starting with ``robocal `` or ``python `` (a span may wrap across lines).

How they run: as written, by bash, in a scratch directory holding the repository's ``examples``, ``calib`` and
``benchmarks`` (so relative paths resolve and outputs land in the scratch directory), with ``robocal`` and
``python`` on PATH meaning this checkout's code.

Quoted figures: the decimal numbers with a unit (mm, deg, °, %) and the "N poses" counts in the sentence that holds
the command, after it -- or, when the command ends its sentence, in the next sentence (none from a sentence that
quotes a duration: speed is no output).  Each must be in the output to the digits quoted (a figure quoted as 2.47 mm
matches 2.4709).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHIPPED_DIRS = ("examples", "calib/data")
TIMEOUT_S = 600


@dataclass
class DocCommand:
    file: Path
    line: int
    command: str
    quote: str                  # the text that quotes figures of its output

    @property
    def id(self) -> str:
        return f"{self.file.name}:{self.line}"


def shipped_names() -> tuple[set[str], set[str]]:
    """(paths relative to the repository, bare file names) of every shipped file."""
    paths = {str(p.relative_to(ROOT)) for d in SHIPPED_DIRS for p in (ROOT / d).rglob("*") if p.is_file()}
    return paths, {Path(p).name for p in paths}


def names_shipped_file(command: str) -> bool:
    paths, bare = shipped_names()
    for tok in re.split(r"[\s=,'\"]+", command):
        tok = tok.rstrip(".;:)")
        if tok in paths or tok in bare or any(tok.startswith(f"{d}/") and tok.rstrip("/") in paths
                                              for d in SHIPPED_DIRS):
            return True
    return False


def _strip_comment(line: str) -> str:
    return re.sub(r"\s{2,}#.*$|\s#\s.*$", "", line).rstrip()


def _sentences(text: str) -> list[str]:
    return [s for s in re.split(r"(?<=[.;])\s+(?=[A-Z(`])", text) if s.strip()]


def doc_commands(path: Path) -> list[DocCommand]:
    """Every command of one Markdown file (see the module docstring)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out: list[DocCommand] = []
    fenced, pending, start = False, "", 0
    para: list[tuple[int, str]] = []

    def flush_paragraph():
        if not para:
            return
        text = "\n".join(t.strip() for _, t in para)
        for m in re.finditer(r"`((?:robocal|python) [^`]+)`", text):
            line = para[0][0] + text[:m.start()].count("\n")
            rest = re.sub(r"\s+", " ", text[m.end():]).strip()
            sentences = _sentences(rest)
            if not rest or rest.startswith((".", ";")):          # the command ends its sentence: the next one
                quote = sentences[1] if len(sentences) > 1 else ""
            else:
                quote = sentences[0] if sentences else ""
            out.append(DocCommand(path, line, re.sub(r"\s+", " ", m.group(1)).strip(), quote))
        para.clear()

    for i, raw in enumerate(lines, 1):
        if raw.lstrip().startswith("```"):
            flush_paragraph()
            fenced = not fenced
            continue
        if fenced:
            line = _strip_comment(raw.strip())
            if pending:
                pending += " " + line.rstrip("\\").strip()
            elif re.match(r"^(\$ )?(robocal|python) ", line):
                pending, start = re.sub(r"^\$ ", "", line.rstrip("\\").strip()), i
            if pending and not line.endswith("\\"):
                out.append(DocCommand(path, start, pending, ""))
                pending = ""
            continue
        if not raw.strip() or raw.lstrip().startswith(("- ", "* ", "#", "|")):
            flush_paragraph()
        if raw.strip():
            para.append((i, raw))
    flush_paragraph()
    return [c for c in out if names_shipped_file(c.command) and not needs_terminal(c.command)]


def needs_terminal(command: str) -> bool:
    """``robocal session`` is the operator's TUI: it refuses to start without a terminal (tests/test_tui_terminal.py
    drives it in one under tmux)."""
    return bool(re.match(r"robocal\s+session\b", command))


def quoted_figures(quote: str) -> list[str]:
    """The figures a sentence quotes from an output; none from a sentence quoting a duration (it is about speed,
    which no output prints)."""
    if re.search(r"(?<![\w.])\d+(?:\.\d+)?\s*(?:s|ms)\b", quote):
        return []
    figs = [m.group(1) for m in re.finditer(r"(?<![\w.])(\d+\.\d+)\s*(?:mm|deg|°|%)", quote)]
    figs += [m.group(1) for m in re.finditer(r"(?<![\w.])(\d+) poses\b", quote)]
    return figs


def in_output(figure: str, output: str) -> bool:
    digits = len(figure.split(".")[1]) if "." in figure else 0
    want = float(figure)
    for m in re.finditer(r"(?<![\w.])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?", output):
        if abs(round(float(m.group(0)), digits) - want) < 0.5 * 10 ** -digits * 1.0001:
            return True
    return False


ALL = [c for doc in DOCS for c in doc_commands(doc)]


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    top = tmp_path_factory.mktemp("docrun")
    tmp = top / "repo"                  # a checkout's place: ../shared (the real data beside it) as in CI
    tmp.mkdir()
    if (ROOT.parent / "shared").is_dir():
        (top / "shared").symlink_to(ROOT.parent / "shared")
    for d in ("examples", "calib", "benchmarks"):
        (tmp / d).symlink_to(ROOT / d)
    bindir = tmp / ".bin"
    bindir.mkdir()
    for name, body in (("robocal", f'exec "{sys.executable}" -m app.cli "$@"'),
                       ("python", f'exec "{sys.executable}" "$@"'), ("python3", f'exec "{sys.executable}" "$@"')):
        f = bindir / name
        f.write_text(f"#!/bin/sh\n{body}\n")
        f.chmod(0o755)
    env = {**os.environ, "PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}",
           "PYTHONPATH": str(ROOT) + (os.pathsep + os.environ["PYTHONPATH"] if os.environ.get("PYTHONPATH") else "")}
    return tmp, env


def test_the_parser_finds_the_examples():
    """The parser itself can fail: it finds commands in blocks and inline spans, with their quotes."""
    cmds = {c.command: c for c in ALL}
    assert any(c.startswith("robocal reprocess examples/demo-session.db") for c in cmds)
    text = ("Run `robocal identify examples/tiago/x.csv --robot\n  examples/tiago/tiago_mocap.toml` — residual 2.47 mm "
            "over the 34 poses. FIGAROH's 4.2 mm is theirs.\n")
    path = ROOT / "tests" / "_doc_probe.md"
    try:
        path.write_text(text)
        (c,) = doc_commands(path)
    finally:
        path.unlink()
    assert c.command == "robocal identify examples/tiago/x.csv --robot examples/tiago/tiago_mocap.toml"
    assert quoted_figures(c.quote) == ["2.47", "34"]
    assert in_output("2.47", "RMS 2.4709 mm") and not in_output("2.47", "RMS 2.4609 mm")


@pytest.mark.parametrize("cmd", ALL, ids=[c.id for c in ALL])
def test_documented_command_runs_as_written(cmd: DocCommand, scratch):
    tmp, env = scratch
    r = subprocess.run(["bash", "-c", cmd.command], cwd=tmp, env=env, capture_output=True, text=True,
                       timeout=TIMEOUT_S)
    output = r.stdout + r.stderr
    assert r.returncode == 0, f"{cmd.id}: `{cmd.command}` exits {r.returncode}: {output.strip()[-600:]}"
    missing = [f for f in quoted_figures(cmd.quote) if not in_output(f, output)]
    assert not missing, f"{cmd.id}: `{cmd.command}`: the text quotes {missing}, not in its output"
