"""The output folder of a CLI run: where summaries, figures, replays and results go.

One folder per run: ``--out DIR`` (re-running a sweep there resumes it), or a
new ``youbot_opt_runs/<command>-<UTC date>-<UTC time>``. It holds what the
command has of ``summary.json``, ``result.npz`` (or ``results/``), ``*.png``
and ``replay.html``; sweeps report progress on stderr through
:class:`ProgressLine`.

>>> folder = run_folder("solve", out=None)  # doctest: +SKIP
"""

from __future__ import annotations

import argparse
import datetime as _dt
import math
import sys
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, TextIO

from youbot_opt._files import StreamedList, atomic_writer, json_ready, write_json_stream

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "DEFAULT_ROOT",
    "add_command",
    "run_folder",
    "json_ready",
    "StreamedList",
    "write_summary",
    "print_json",
    "save_figure",
    "print_outputs",
    "ProgressLine",
]

DEFAULT_ROOT = Path("youbot_opt_runs")
"""Parent of the per-run folders made when no ``--out`` is given (relative to the cwd)."""


def add_command(
    sub: argparse._SubParsersAction,  # type: ignore[type-arg]
    name: str,
    *,
    help: str,  # noqa: A002 - the argparse keyword
    description: str,
    **kwargs: Any,
) -> argparse.ArgumentParser:
    """Add one sub-command to the dispatcher and return its parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The dispatcher's sub-parsers.
    name : str
        The sub-command (``youbot-opt NAME``).
    help : str
        One line for ``youbot-opt --help``.
    description : str
        The text at the top of ``youbot-opt NAME --help``.
    **kwargs
        Further :meth:`argparse._SubParsersAction.add_parser` keywords
        (``epilog``, ``formatter_class``).

    Returns
    -------
    argparse.ArgumentParser
        The sub-command's parser, for its arguments.
    """
    parser: argparse.ArgumentParser = sub.add_parser(
        name, help=help, description=description, **kwargs
    )
    return parser


def run_folder(
    command: str, out: str | Path | None = None, *, root: str | Path | None = None
) -> Path:
    """Create (if needed) and return the output folder of one run.

    Parameters
    ----------
    command
        Sub-command name, used in the default folder name (e.g. ``"solve"``).
    out
        Folder chosen by the user (``--out``); created with its parents and
        reused if it exists (sweeps resume from it).
    root
        Parent of default folders; ``youbot_opt_runs`` in the cwd when omitted.

    Returns
    -------
    Path
        The folder, which exists on return.
    """
    if out is not None:
        folder = Path(out)
        if folder.exists() and not folder.is_dir():
            raise NotADirectoryError(f"--out {folder}: exists and is not a directory")
        folder.mkdir(parents=True, exist_ok=True)
        return folder
    parent = Path(root) if root is not None else DEFAULT_ROOT
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%d-%H%M%S")
    base = parent / f"{command}-{stamp}"
    for n in range(1, 1000):
        folder = base if n == 1 else base.with_name(f"{base.name}-{n}")
        try:
            folder.mkdir(parents=True, exist_ok=False)
        except FileExistsError:
            continue
        return folder
    raise FileExistsError(f"could not create a new run folder next to {base}")  # pragma: no cover


def write_summary(
    folder: str | Path, summary: Mapping[str, Any], name: str = "summary.json"
) -> Path:
    """Write ``summary`` as indented JSON to ``folder/name`` atomically; return the path.

    A :class:`~youbot_opt._files.StreamedList` in ``summary`` (a sweep's
    per-start rows) is written one item at a time, so the file's size, not
    the document's, never sits in memory.
    """
    path = Path(folder) / name
    with atomic_writer(path) as handle:
        write_json_stream(handle, json_ready(summary))
    return path


def print_json(doc: Mapping[str, Any], stream: IO[str] | None = None) -> None:
    """Print ``doc`` as indented JSON (``--json``) to stdout, streaming its long lists."""
    write_json_stream(sys.stdout if stream is None else stream, json_ready(doc))


def save_figure(fig: Figure, folder: str | Path, name: str, *, dpi: int = 120) -> Path:
    """Save a matplotlib figure as ``folder/name`` (PNG unless a suffix is given); close it."""
    import matplotlib.pyplot as plt

    path = Path(folder) / (name if Path(name).suffix else f"{name}.png")
    fig.savefig(path, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return path


def print_outputs(
    folder: str | Path, files: Iterable[str | Path] = (), stream: IO[str] | None = None
) -> None:
    """Print the run folder and the files written in it.

    Goes to stderr by default, so that ``--json`` keeps stdout one JSON object.
    """
    out = sys.stderr if stream is None else stream
    folder = Path(folder)
    print(f"output folder: {folder.resolve()}", file=out)
    for f in files:
        p = Path(f)
        try:
            shown = p.relative_to(folder)
        except ValueError:
            shown = p
        print(f"  {shown}", file=out)


class ProgressLine:
    """Progress line of a sweep on stderr: rewritten in place on a terminal, else one per item.

    Parameters
    ----------
    label : str
        Shown first (the command, e.g. ``"multistart"``).
    quiet : bool
        Print nothing.
    stream : text stream, optional
        Where to print (default: stderr).
    """

    def __init__(self, label: str, quiet: bool, stream: TextIO | None = None) -> None:
        self.label = label
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.tic = time.perf_counter()

    def __call__(self, done: int, total: int, last: Any) -> None:
        """Report item ``done`` of ``total``; ``last`` is the sweep's item (status, objective)."""
        if self.quiet:
            return
        f = getattr(last, "objective", math.nan)
        what = getattr(last, "key", None) or f"beta={getattr(last, 'beta', '?')}"
        line = (
            f"{self.label}: {done}/{total} [{time.perf_counter() - self.tic:6.1f} s] "
            f"{what}: {last.status} f={f:.6g}"
        )
        end = "" if self.tty else "\n"
        self.stream.write(("\r" if self.tty else "") + line + end)
        self.stream.flush()

    def close(self) -> None:
        """End the in-place line on a terminal."""
        if self.tty and not self.quiet:
            self.stream.write("\n")
