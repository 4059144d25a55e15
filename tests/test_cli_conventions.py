"""Command-line conventions (issue 26, item 3), walked over every command and subcommand: no option is abbreviated
(a typo is an error naming the option, exit 2), every ``--help`` has examples that parse and states the defaults,
``--robot`` reads the same everywhere, and ``session`` without a terminal refuses in one line."""
import argparse
import contextlib
import io
import shlex
import subprocess
import sys

import pytest

from acq.argtypes import ROBOT_HELP
from app.cli import build_parser, command_index


def _parsers():
    """(name, parser) of the top level, every command and every subcommand (each command's module imported)."""
    out = [("robocal", build_parser())]
    for name in command_index():
        top = build_parser(only=name)
        stack = [(name, top._subparsers._group_actions[0].choices[name])]
        while stack:
            label, p = stack.pop()
            out.append((label, p))
            for a in p._actions:
                if isinstance(a, argparse._SubParsersAction):
                    stack += [(f"{label} {sub}", sp) for sub, sp in a.choices.items()]
    return out


PARSERS = _parsers()


def _has_subcommands(p) -> bool:
    return any(isinstance(a, argparse._SubParsersAction) for a in p._actions)


@pytest.mark.parametrize("name,parser", PARSERS, ids=[n for n, _ in PARSERS])
def test_every_help_has_examples_and_states_its_defaults_and_no_option_is_abbreviated(name, parser):
    assert parser.allow_abbrev is False, name
    text = parser.format_help()
    assert "examples:\n  robocal " in text, f"{name}: --help has no example"
    fmt = parser._get_formatter()
    for a in parser._actions:
        if not a.option_strings or a.help == argparse.SUPPRESS or isinstance(a, argparse._HelpAction):
            continue
        assert a.help, f"{name} {a.option_strings[0]}: no help"
        d = a.default
        if d is None or d is False or (isinstance(d, list) and not d):
            continue
        assert "default" in fmt._expand_help(a), f"{name} {a.option_strings[0]}: default {d!r} not stated"
    robot = [a for a in parser._actions if "--robot" in a.option_strings]
    if robot:
        assert robot[0].help.startswith(ROBOT_HELP), f"{name}: --robot described differently"


def test_every_example_parses():
    """Each example of each --help is a valid command line (files need not exist: only the parse is checked)."""
    bad = []
    for name, parser in PARSERS:
        examples = (parser.epilog or "").split("examples:\n", 1)[-1]
        for line in examples.replace("\\\n", " ").splitlines():
            words = shlex.split(line.split("#", 1)[0])
            if not words or words[0] != "robocal" or "COMMAND" in words:
                continue
            err = io.StringIO()
            try:
                with contextlib.redirect_stderr(err):
                    build_parser(only=words[1]).parse_args(words[1:])
            except SystemExit as exc:
                if exc.code and "file not found" not in err.getvalue():       # an example's own file: fine
                    bad.append(f"{line.strip()}: {err.getvalue().strip()}")
    assert not bad, bad


@pytest.mark.parametrize("args,named", [
    (["session", "--emulat"], "unknown option --emulat (did you mean --emulate?)"),
    (["demo", "--see", "3"], "unknown option --see (did you mean --seed?)"),
    (["plan", "poses", "--cont", "3"], "plan poses: unknown option --cont (did you mean --count?)"),
])
def test_a_prefix_or_typo_is_an_error_naming_the_option(args, named):
    r = subprocess.run([sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and named in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_session_without_a_terminal_refuses_in_one_line(tmp_path):
    db = tmp_path / "n.db"
    r = subprocess.run([sys.executable, "-m", "app.cli", "session", "--emulate", "--db", str(db)],
                       stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.startswith("robocal: error: session: needs a terminal"), r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and not db.exists()
