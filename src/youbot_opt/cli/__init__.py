"""Command line interface: ``youbot-opt <command> [options]``.

:func:`main` parses the command line (:mod:`youbot_opt.cli.parser`, which
imports nothing heavy, so ``--help`` stays fast), then imports only the chosen
command's module and runs it: ``run(args) -> int``, the process exit code.
Running ``youbot-opt`` with no command runs the main job (``youbot-opt main``).

>>> main(["report", "--robot", "ur5"])  # doctest: +SKIP
"""

from __future__ import annotations

import importlib
import logging
import sys
from collections.abc import Sequence

from youbot_opt.cli.parser import COMMANDS, build_parser, cut_long_values, parse
from youbot_opt.cli.warning_lines import warnings_as_lines
from youbot_opt.exceptions import YoubotOptError

__all__ = ["main", "build_parser"]


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
    args = parse(argv)
    module_name, function = COMMANDS[args.command]
    module = importlib.import_module(f"youbot_opt.cli.{module_name}")
    _show_compile_progress()
    try:
        with warnings_as_lines():  # one line per warning, grouped, no source lines
            return int(getattr(module, function)(args))
    except YoubotOptError as exc:
        print(f"youbot-opt: error: {cut_long_values(str(exc), argv)}", file=sys.stderr)
        return 2
    except OSError as exc:  # a path the system refused: one line naming it, what it needs
        from youbot_opt.cli.output_errors import os_error_line  # not before: --help stays light

        print(f"youbot-opt: error: {cut_long_values(os_error_line(exc), argv)}", file=sys.stderr)
        return 2
    except (MemoryError, RecursionError) as exc:  # last resort: limits are checked before
        what = "memory" if isinstance(exc, MemoryError) else "stack"
        print(f"youbot-opt: error: out of {what} (a size no limit foresaw; please report it)",
              file=sys.stderr)  # fmt: skip
        return 2
