"""The multistart part of ``youbot-opt ikpath`` that the planar and spatial modes share.

The progress of the starts on stderr (:class:`StartProgress`), the
:class:`~youbot_opt.sweeps.options.SweepOptions` of the command line
(:func:`start_sweep`: workers, progress, the run folder as the resumable store,
``--shard``), the per-start rows of ``starts.jsonl`` (:func:`write_starts`)
and the printed lines about the starts (:func:`print_starts`).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import NamedTuple, TextIO

from youbot_opt._files import write_json_lines
from youbot_opt._typing import JSONDict
from youbot_opt.ikpath.result import IKPathResult
from youbot_opt.ikpath.stored import StartSummary, StoredResults
from youbot_opt.sweeps.options import SweepOptions

__all__ = [
    "STARTS_FILE",
    "StartProgress",
    "StartsFile",
    "print_starts",
    "start_sweep",
    "write_starts",
]

STARTS_FILE = "starts.jsonl"
"""The run folder's per-start rows, one JSON object a line (named in ``summary.json``)."""


class StartProgress:
    """Progress of the starts on stderr: a bar on a terminal, else a line per tenth."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.tic = time.perf_counter()
        self.shown = -1

    def __call__(self, done: int, total: int, best: float) -> None:
        """Report ``done`` of ``total`` starts and the best ``E`` so far [rad^2]."""
        best_txt = f"{best:.10g} rad^2" if math.isfinite(best) else "none converged yet"
        elapsed = time.perf_counter() - self.tic
        if self.tty:
            width = 30
            fill = int(width * done / total)
            self.stream.write(
                f"\r[{'#' * fill}{'.' * (width - fill)}] {done}/{total} starts, "
                f"best E {best_txt}, {elapsed:.1f} s"
            )
            if done == total:
                self.stream.write("\n")
        else:
            tenth = 10 * done // total
            if tenth == self.shown and done != total:
                return
            self.shown = tenth
            self.stream.write(
                f"ikpath: {done}/{total} starts done, best E {best_txt}, {elapsed:.1f} s\n"
            )
        self.stream.flush()


def start_sweep(args: argparse.Namespace, folder: Path, executor: str) -> SweepOptions:
    """Return how the starts of the command line run, and say on stderr where they are saved.

    Parameters
    ----------
    args : argparse.Namespace
        ``--starts``, ``--workers`` (default: 1 below 8 starts, else the CPUs),
        ``--no-progress``, ``--shard`` and ``--keep-results/--no-keep-results``.
    folder : Path
        The run folder: the sweep store, which a rerun with ``--out`` resumes.
    executor : str
        A Dask scheduler address, ``"process"`` (several starts: a crashing
        start cannot end the run) or ``"serial"``.
    """
    workers = args.workers if args.workers is not None else (1 if args.starts < 8 else None)
    if not args.no_progress:
        print(
            f"ikpath: {args.starts} start(s), each saved to {folder.resolve() / 'items'} as it "
            f"finishes (rerun with --out {folder} to resume)",
            file=sys.stderr,
        )
    return SweepOptions(
        executor=executor,
        workers=workers,
        progress=None if args.no_progress else StartProgress(),
        out=folder,
        shard=args.shard,
        keep_results=getattr(args, "keep_results", True),
    )


class StartsFile(NamedTuple):
    """What :func:`write_starts` wrote: the file, and what the printed summary needs of it."""

    path: Path
    """``starts.jsonl`` in the run folder."""
    retried: list[int]
    """Indices of the starts that needed more than one attempt."""
    crashed: list[JSONDict]
    """The rows of the starts that crashed on every attempt (their ``message`` says why)."""


def write_starts(
    folder: Path,
    results: Sequence[IKPathResult],
    attempts: Sequence[int],
    detail: Callable[[IKPathResult | StartSummary[IKPathResult]], JSONDict] | None = None,
) -> StartsFile:
    """Write one JSON object per start to ``folder/starts.jsonl`` (:data:`STARTS_FILE`).

    Each row holds ``index``, ``status``, ``E`` [rad^2], the ``detail`` fields,
    ``attempts`` (``null``: unknown) and ``message`` (``null`` on a success).

    Parameters
    ----------
    folder : Path
        The run folder.
    results : sequence of IKPathResult
        One result per start, in start order (``--no-keep-results``: a
        :class:`~youbot_opt.ikpath.stored.StoredResults`, whose journal
        summaries are read instead, one at a time: a sweep of a million starts
        is never held in memory).
    attempts : sequence of int
        Attempts per start (empty: unknown).
    detail : callable ``(result or StartSummary) -> dict``, optional
        Mode-specific fields of each start, written after ``E``.

    Returns
    -------
    StartsFile
        The file, the retried starts and the crashed starts' rows.
    """
    crashed: list[JSONDict] = []

    def row(
        index: int, status: str, r: IKPathResult | StartSummary[IKPathResult], attempts: int | None
    ) -> JSONDict:
        out: JSONDict = {
            "index": index,
            "status": status,
            "E": r.objective,
            **({} if detail is None else detail(r)),
            "attempts": attempts,
            "message": None if r.success else r.message,
        }
        if status == "crashed":
            crashed.append(out)
        return out

    rows: Iterable[JSONDict]
    if isinstance(results, StoredResults):  # streamed from the journal, never all in memory
        rows = (row(s.index, s.status, s, s.attempts) for s in results.summaries())
        retried = [s.index for s in results.summaries() if s.attempts > 1]
    else:
        rows = (
            row(i, r.status.value, r, attempts[i] if attempts else None)
            for i, r in enumerate(results)
        )
        retried = [i for i, a in enumerate(attempts) if a > 1]
    path = folder / STARTS_FILE
    write_json_lines(path, rows)
    return StartsFile(path, retried, crashed)


def print_starts(doc: Mapping[str, object], crashed: Sequence[Mapping[str, object]]) -> None:
    """Print how the starts ran: throughput and outcomes, resumed, retried and crashed starts.

    ``doc`` is the run's summary (``starts``, ``seed``, ``start_kind``,
    ``workers``, ``wall_time`` [s], ``starts_per_second`` [1/s],
    ``status_counts``, ``resumed`` and ``retried``); ``crashed`` the rows of
    :attr:`StartsFile.crashed`.
    """
    print(
        f"multistart: {doc['starts']} starts (seed {doc['seed']}, {doc['start_kind']}), "
        f"{doc['workers']} workers, {doc['wall_time']:.2f} s "
        f"({doc['starts_per_second']:.1f} starts/s); outcomes {doc['status_counts']}"
    )
    if doc["resumed"]:
        print(f"  {doc['resumed']} starts loaded from the output folder (resumed)")
    if doc["retried"]:
        print(f"  retried after a failed attempt: starts {doc['retried']}")
    for o in crashed:
        print(f"  start {o['index']} failed after {o['attempts']} attempts: {o['message']}")
