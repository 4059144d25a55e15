"""The ``robocal`` command line: one console script, one subcommand per module in :mod:`acq.commands`.

A command module defines ``NAME``, ``HELP`` and ``add_arguments(parser)`` and ``run(args) -> int``; it is found by
scanning the package, so a new command is one new file (a registry, not an if/elif chain).  Errors the operator can fix
(:class:`calib.errors.RobocalError`) print one line, ``robocal: error: ...``, and exit with status 2.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from calib.errors import RobocalError

from . import commands


def _command_modules():
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{commands.__name__}.{info.name}")
        if hasattr(mod, "NAME") and hasattr(mod, "run"):
            yield mod


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="robocal",
        description="Calibrate an industrial robot with two theodolites and a joint-encoder tap.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod in _command_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP))
        mod.add_arguments(p)
        _add_chain_cut(p)
        p.set_defaults(_run=mod.run)
    return parser


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
    from calib.robot import RobotPath
    base, tip = getattr(args, "base_link", None), getattr(args, "tip_link", None)
    if base or tip:
        if not getattr(args, "robot", None):
            raise RobocalError("--base-link / --tip-link need --robot FILE.urdf")
        args.robot = RobotPath(args.robot, base, tip)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 0
    try:
        _apply_chain_cut(args)
        return int(args._run(args) or 0)
    except RobocalError as exc:
        print(f"robocal: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("robocal: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
