"""The ``mjjoint`` command line: ``mjjoint <command> [options]``.

Each command is a module of this package with ``register(subparsers)``, which adds its
parser and sets ``handler`` (a function of the parsed arguments returning the exit code).
Adding a command = adding its module name to ``COMMANDS``.
"""
from __future__ import annotations

import importlib
from importlib.metadata import version
from collections.abc import Sequence

from .errors import PROG, ArgumentParser, CliError, guarded

COMMANDS = ("simulate", "fit", "diagnose", "design")

__all__ = ["COMMANDS", "CliError", "build_parser", "main"]


def build_parser() -> ArgumentParser:
    parser = ArgumentParser(prog=PROG, description="Elastic robot joints (Ruderman 2012) in MuJoCo.")
    parser.add_argument("--version", action="version", version=f"{PROG} {version('mjjoint')}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mjjoint`` script; returns the exit code (2 for a user error)."""
    def command() -> int:
        args = build_parser().parse_args(argv)
        return args.handler(args)
    return guarded(command)
