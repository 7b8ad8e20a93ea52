"""Command line interface: ``youbot-opt <command> [options]``.

Each sub-command lives in its own module of this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable
``func(args) -> int`` (the process exit code). Running ``youbot-opt`` with no
command runs the main job (``youbot-opt main``).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import re
import sys
from collections.abc import Sequence
from typing import NoReturn

from youbot_opt._checks import MAX_SHOWN_CHARS
from youbot_opt._version import __version__
from youbot_opt.exceptions import YoubotOptError

__all__ = ["main", "build_parser"]

#: Sub-command modules, in the order they appear in ``--help``.
_COMMAND_MODULES: tuple[str, ...] = (
    "main_command",
    "solve",
    "report",
    "robots",
    "studies",
    "reproduce",
    "ikpath",
)

DEFAULT_COMMAND = "main"


_LONG_RUN = re.compile(rf"\S{{{MAX_SHOWN_CHARS + 1},}}")
_ARGV: list[str] = []  # the command line being parsed, for the parser's error messages


def _cut(text: str) -> str:
    return f"{text[:MAX_SHOWN_CHARS]}… ({len(text)} characters)"


def cut_long_values(message: str, argv: Sequence[str] = ()) -> str:
    """Cut, in an error message, every echoed value longer than ``MAX_SHOWN_CHARS``.

    The values of ``argv`` (also the ``VALUE`` of ``--flag=VALUE``) are cut
    where they appear, spaces and all; any other run of more than
    ``MAX_SHOWN_CHARS`` non-space characters is cut too. Each cut ends in
    ``… (N characters)``.
    """
    values = {a.split("=", 1)[1] if a.startswith("--") and "=" in a else a for a in argv}
    for value in sorted((v for v in values if len(v) > MAX_SHOWN_CHARS), key=len, reverse=True):
        message = message.replace(value, _cut(value))
    return _LONG_RUN.sub(lambda m: _cut(m.group()), message)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose error messages cut long values (sub-parsers are one too)."""

    def error(self, message: str) -> NoReturn:
        super().error(cut_long_values(message, _ARGV or sys.argv[1:]))


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level argument parser with every sub-command registered.

    Returns
    -------
    argparse.ArgumentParser
        The parser; each sub-parser sets ``func``.
    """
    parser = _Parser(
        prog="youbot-opt",
        description="Trajectory and IK-path optimisation of rigid-body arms (Pinocchio + CasADi).",
    )
    parser.add_argument("--version", action="version", version=f"youbot_opt {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in _COMMAND_MODULES:
        module = importlib.import_module(f"youbot_opt.cli.{name}")
        module.register(sub)
    return parser


class _StderrHandler(logging.StreamHandler):  # type: ignore[type-arg]
    """Write to whatever ``sys.stderr`` is at the time of each record (tests swap it)."""

    @property  # type: ignore[override]
    def stream(self) -> object:
        return sys.stderr

    @stream.setter
    def stream(self, value: object) -> None:
        pass


def _show_compile_progress() -> None:
    """Show on stderr what the C compilation of dynamics kernels is doing (it can take minutes)."""
    log = logging.getLogger("youbot_opt.nlp.codegen")
    if not any(isinstance(h, _StderrHandler) for h in log.handlers):
        handler = _StderrHandler()
        handler.setFormatter(logging.Formatter("youbot-opt: %(message)s"))
        log.addHandler(handler)
        log.setLevel(logging.INFO)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line and return the exit code.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when omitted.

    Returns
    -------
    int
        0 on success, 1 on a failed solve, 2 on bad input.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    if not argv or argv[0].startswith("-") and argv[0] not in ("-h", "--help", "--version"):
        argv = [DEFAULT_COMMAND, *argv]
    _ARGV[:] = argv
    args = parser.parse_args(argv)
    _show_compile_progress()
    from youbot_opt.cli.warning_lines import warnings_as_lines

    try:
        with warnings_as_lines():  # one line per warning, grouped, no source lines
            return int(args.func(args))
    except YoubotOptError as exc:
        print(f"youbot-opt: error: {cut_long_values(str(exc), argv)}", file=sys.stderr)
        return 2
    except (MemoryError, RecursionError) as exc:  # last resort: limits are checked before
        what = "memory" if isinstance(exc, MemoryError) else "stack"
        print(f"youbot-opt: error: out of {what} (a size no limit foresaw; please report it)",
              file=sys.stderr)  # fmt: skip
        return 2
