"""The ``robocal`` command line: one console script, one subcommand per module in :mod:`app.commands`.

A command module defines ``NAME``, ``HELP`` and ``add_arguments(parser)`` and ``run(args) -> int``; it is found by
scanning the package, so a new command is one new file (a registry, not an if/elif chain).

Exit status and messages (docs/user-guide.md, "Errors and exit status"):

- 0: done.
- 2: bad input the operator can fix -- an option (checked at parse time by :mod:`acq.argtypes`), a file, a device.
  One line on stderr: ``robocal: error: WHERE: what is wrong``.
- 3: an internal error (a bug).  The last-resort handler prints one line naming the command and the exception;
  ``robocal --debug ...`` (or ``ROBOCAL_DEBUG=1``) prints the traceback as well.
- 130: interrupted with Ctrl-C.

Threads: the command runs BLAS/LAPACK on one thread (robocal's matrices are too small to gain from more; see
:mod:`calib.threads`) unless the user sets ``--threads N``, ``ROBOCAL_THREADS=N`` or a BLAS variable of their own.
The count is set before numpy is imported, so this module and everything it imports at module level stay free of
numpy; each command's module is imported only when that command runs.
"""
from __future__ import annotations

import argparse
import ast
import contextlib
import gc
import importlib
import os
import re
import sys
import warnings

from calib import threads
from calib.errors import RobocalError

from app import commands
from acq.argtypes import examples_text

EXIT_OK, EXIT_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED = 0, 2, 3, 130
TOP_EXAMPLES = """\
robocal demo                                  # record an emulated session and calibrate from it
robocal session --emulate --db cell.db        # the operator's TUI on the emulated cell
robocal reprocess cell.db --report report/    # calibrate from a recorded session, write the report
robocal COMMAND --help                        # each command's options, defaults and examples
"""


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Every option states its default: where its help does not say it already, ``(default: X)`` is added; the
    examples (the epilog) keep their lines."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        d = action.default
        unset = d is None or d is False or d is argparse.SUPPRESS or (isinstance(d, list) and not d)
        if action.option_strings and "default" not in text and not unset and action.nargs != 0:
            text += " (default: %(default)s)"
        return text


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, ``robocal: error: COMMAND: --opt must be ...`` (exit 2).

    No option is ever abbreviated (``--emulat`` is not ``--emulate``: a typo must be an error naming the option, not
    a guess), and every parser formats its help with :class:`_HelpFormatter`."""

    def __init__(self, *args, **kwargs):
        kwargs["allow_abbrev"] = False
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def parse_known_args(self, args=None, namespace=None):
        """A command's parser refuses what it does not know itself, so the error names the command and the closest
        option (argparse leaves the extras to the top-level parser, which knows neither)."""
        ns, extras = super().parse_known_args(args, namespace)
        if extras and " " in self.prog:
            self.error(self._unknown(extras))
        return ns, extras

    def _unknown(self, extras: list[str]) -> str:
        import difflib
        options = [o for o in self._option_string_actions if o.startswith("--")]
        first = extras[0]
        if first.startswith("-"):
            name = first.split("=", 1)[0]
            close = difflib.get_close_matches(name, options, n=1, cutoff=0.6)
            return f"unknown option {name}" + (f" (did you mean {close[0]}?)" if close else "")
        return f"unexpected argument {first!r}"

    def error(self, message: str):  # type: ignore[override]
        where = self.prog.split(" ", 1)[1] + ": " if " " in self.prog else ""
        # "argument --rate-hz: must be positive" reads better as "--rate-hz must be positive"
        message = re.sub(r"^argument ([^:]+): (must|is|file not found)", r"\1 \2", message)
        message = re.sub(r"^argument ", "", message)
        self.exit(EXIT_INPUT, f"robocal: error: {where}{' '.join(message.split())} (see --help)\n")


#: where a module's body starts: the constants stand above it, so only the head is parsed (the whole file is the
#: fallback); parsing every command file whole took half of ``robocal --help``
_BODY_START = re.compile(r"^(?:def |class |async def |@|if __name__)", re.M)


def _constants(path: str) -> dict[str, str]:
    """The module-level string constants of a source file (``NAME``, ``HELP``, ``DESCRIPTION``), read without
    importing it: a command's module imports numpy, scipy and the model, which ``robocal --help`` does not need."""
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    body = _BODY_START.search(text)
    out: dict[str, str] = {}
    for source in ([text[:body.start()]] if body else []) + [text]:
        out = _literal_constants(ast.parse(source, path))
        if "NAME" in out and "HELP" in out and "EXAMPLES" in out:
            break
    return out


def _literal_constants(tree: ast.Module) -> dict[str, str]:
    out = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and node.targets[0].id in ("NAME", "HELP", "DESCRIPTION", "EXAMPLES"):
            try:
                out[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:          # not a literal: the module is imported to read it
                pass
    return out


def command_index() -> dict[str, tuple[str, str, str, str]]:
    """Every command: NAME -> (module, HELP, DESCRIPTION, EXAMPLES), by scanning the package (a new command is one
    new file)."""
    index = {}
    folder = commands.__path__[0]
    # the folder listed directly (pkgutil costs more to import than the listing takes)
    for name in sorted(f[:-3] for f in os.listdir(folder) if f.endswith(".py") and not f.startswith("_")):
        module = f"{commands.__name__}.{name}"
        c = _constants(os.path.join(folder, f"{name}.py"))
        if "NAME" not in c or "HELP" not in c:
            mod = importlib.import_module(module)
            if not (hasattr(mod, "NAME") and hasattr(mod, "run")):
                continue
            c = {"NAME": mod.NAME, "HELP": mod.HELP, "DESCRIPTION": getattr(mod, "DESCRIPTION", mod.HELP),
                 "EXAMPLES": getattr(mod, "EXAMPLES", "")}
        index[c["NAME"]] = (module, c["HELP"], c.get("DESCRIPTION", c["HELP"]), c.get("EXAMPLES", ""))
    return index


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The whole command line; with ``only`` naming a command, only that command's module is imported and only its
    parser is built (16 argparse parsers cost ~20 ms), so a command starts without loading every other command's
    dependencies; with none (``robocal --help``) or an unknown word, every command is listed and none imported."""
    parser = _Parser(
        prog="robocal",
        description="Calibrate an industrial robot with two theodolites and a joint-encoder tap.",
        epilog=examples_text(TOP_EXAMPLES))
    parser.add_argument("--debug", action="store_true",
                        help="on an internal error (exit 3) show the Python traceback (also ROBOCAL_DEBUG=1)")
    parser.add_argument("--threads", metavar="N", type=int,
                        help=f"threads for the linear algebra (BLAS); default {threads.DEFAULT_THREADS}, or "
                             f"${threads.THREADS_ENV}; a BLAS variable you set yourself (OMP_NUM_THREADS, "
                             "OPENBLAS_NUM_THREADS, MKL_NUM_THREADS) is respected when neither is given")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    index = command_index()
    if only in index:
        index = {only: index[only]}
    for name, (module, help_, description, examples) in index.items():
        p = sub.add_parser(name, help=help_, description=description, epilog=examples_text(examples))
        if only is None or only == name:
            mod = importlib.import_module(module)
            mod.add_arguments(p)
            _add_chain_cut(p)
            p.set_defaults(_run=mod.run)
    return parser


def _selected_command(argv: list[str]) -> str:
    """The command word of ``argv`` ("" when there is none: the top-level help needs no command module)."""
    words = [a for a in argv if not a.startswith("-")]
    return words[0] if words else ""


def _add_chain_cut(p: argparse.ArgumentParser) -> None:
    """Every parser taking ``--robot`` also takes ``--base-link`` / ``--tip-link`` (a URDF's chain cut)."""
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                _add_chain_cut(sub)
    if "--robot" in p._option_string_actions and "--base-link" not in p._option_string_actions:
        p.add_argument("--base-link", metavar="LINK", help="URDF: the link the chain starts from (default: the root)")
        p.add_argument("--tip-link", metavar="LINK",
                       help="URDF: the link the chain ends at (default: the only moving leaf)")


def _apply_chain_cut(args: argparse.Namespace) -> None:
    from calib.loading import RobotPath
    base, tip = getattr(args, "base_link", None), getattr(args, "tip_link", None)
    if base or tip:
        if not getattr(args, "robot", None):
            raise RobocalError("--base-link / --tip-link need --robot FILE.urdf")
        args.robot = RobotPath(args.robot, base, tip)


def _threads_option(argv: list[str]) -> tuple[int | None, list[str]]:
    """``--threads N`` / ``--threads=N`` taken out of ``argv`` (accepted anywhere on the line, like ``--debug``):
    it must act before the command's module, and with it numpy, is imported."""
    rest, requested, i = [], None, 0
    while i < len(argv):
        a = argv[i]
        if a == "--threads" or a.startswith("--threads="):
            raw = a.partition("=")[2] if "=" in a else (argv[i + 1] if i + 1 < len(argv) else "")
            i += 1 if "=" in a else 2
            try:
                requested = threads.parse_threads(raw, "--threads")
            except ValueError as exc:
                raise RobocalError(str(exc)) from None
            continue
        rest.append(a)
        i += 1
    return requested, rest


def _blas_threads(requested: int | None):
    """Fix the BLAS thread count for this run (see :mod:`calib.threads`): through the environment when numpy is not
    loaded yet (the ``robocal`` command), else a limit on the loaded libraries (robocal called from Python)."""
    try:
        n = threads.wanted(requested) if "numpy" in sys.modules else threads.configure(requested)
    except ValueError as exc:
        raise RobocalError(str(exc)) from None
    return threads.limit(n)


def _debug_wanted(argv: list[str]) -> bool:
    return "--debug" in argv or os.environ.get("ROBOCAL_DEBUG", "") not in ("", "0")


def _command_name(argv: list[str]) -> str:
    words = [a for a in argv if not a.startswith("-")]
    return words[0] if words else "robocal"


def _internal_error(exc: BaseException, argv: list[str], debug: bool) -> int:
    """The last-resort handler: an exception nobody turned into a RobocalError is a bug, reported in one line."""
    if debug:
        import traceback
        traceback.print_exception(exc, file=sys.stderr)
    text = " ".join(str(exc).split())[:300]
    detail = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    hint = "" if debug else "; run again with robocal --debug for the traceback"
    print(f"robocal: internal error in '{_command_name(argv)}': {detail} (a bug, please report it{hint})",
          file=sys.stderr)
    return EXIT_INTERNAL


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Python warnings (unknown CSV columns, ...) reach the operator as one line, not as source file and line."""
    print(f"robocal: warning: {' '.join(str(message).split())}", file=file or sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """The ``robocal`` command; ``argv`` None: this process's own command line (the console script, ``python -m
    app.cli``), which then ends with the command."""
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            return _main(argv)
    finally:
        if argv is None:
            # the interpreter's shutdown runs a full garbage collection over every object the command made (the
            # demo's modules, twin, plan, results): frozen, they are skipped -- the demo's exit went from 100-470 ms
            # to 30-100 ms after its last line (2026-11-26, the 2-core machine at load 0.9-2.9).  A caller in the same
            # process passes ``argv`` and keeps its collector as it was
            gc.freeze()


def _main(argv: list[str] | None) -> int:
    own_process = argv is None                  # this process's command line: the process ends with the command
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = _debug_wanted(argv)
    argv = [a for a in argv if a != "--debug"]  # accepted anywhere on the line, not only before the command
    try:
        requested, argv = _threads_option(argv)
        with _blas_threads(requested):
            return _run(argv, debug, own_process)
    except RobocalError as exc:
        print(f"robocal: error: {exc}", file=sys.stderr)
        return EXIT_INPUT


@contextlib.contextmanager
def _collector_paused(own_process: bool):
    """No cyclic garbage collection while the command's modules are imported: they make objects that live as long as
    the process, which 40 collections traversed again and again (10-30 ms of the demo's start).  In the process's own
    command (``own_process``) they are then frozen: the first collection after the pause would have traversed them all
    once more (21 ms); a caller in the same process gets its collector back as it was, nothing frozen."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if own_process:
            gc.freeze()
        if was:
            gc.enable()


def _run(argv: list[str], debug: bool, own_process: bool = False) -> int:
    try:
        with _collector_paused(own_process):
            parser = build_parser(only=_selected_command(argv))
            try:
                args = parser.parse_args(argv)
            except SystemExit as exc:  # --help (0) or a bad option (2, already printed as one line)
                return exc.code if isinstance(exc.code, int) else EXIT_INPUT
            if not getattr(args, "_run", None):
                parser.print_help()
                return EXIT_OK
            _apply_chain_cut(args)
            # dataclasses (and this table) only once a command runs: --help makes none
            from app import dataclass_code
            dataclass_code.install()            # the command's modules make their dataclasses from compiled code kept
        return int(args._run(args) or 0)
    except RobocalError as exc:
        print(f"robocal: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("robocal: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        return EXIT_OK
    except OSError as exc:
        if exc.filename is None:
            return _internal_error(exc, argv, debug)
        # a file the operator named (or the directory it goes into): fixable by the operator
        print(f"robocal: error: {exc.filename}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_INPUT
    except Exception as exc:  # noqa: BLE001 -- the last-resort handler
        return _internal_error(exc, argv, debug)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
