"""The multistart part of ``youbot-opt ikpath`` that the planar and spatial modes share.

The progress of the starts on stderr (:class:`StartProgress`), the
:class:`~youbot_opt.sweeps.options.SweepOptions` of the command line
(:func:`start_sweep`: workers, progress, the run folder as the resumable store,
``--shard``), the per-start fields of ``summary.json`` (:func:`start_fields`)
and the printed lines about the starts (:func:`print_starts`).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from youbot_opt.sweeps.options import SweepOptions

if TYPE_CHECKING:
    from youbot_opt.ikpath.result import IKPathResult

__all__ = ["StartProgress", "print_starts", "start_fields", "start_sweep"]


class StartProgress:
    """Progress of the starts on stderr: a bar on a terminal, else a line per tenth."""

    def __init__(self, stream: Any = None) -> None:
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


def start_fields(
    results: Sequence[IKPathResult],
    attempts: Sequence[int],
    detail: Callable[[Any], dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """Return the per-start fields of ``summary.json``: ``retried`` and ``start_outcomes``.

    Parameters
    ----------
    results : sequence of IKPathResult
        One result per start, in start order (``--no-keep-results``: a
        :class:`~youbot_opt.ikpath.stored.StoredResults`, whose journal
        summaries are read instead of the results).
    attempts : sequence of int
        Attempts per start (empty: unknown, written as ``null``).
    detail : callable ``(result or StartSummary) -> dict``, optional
        Mode-specific fields of each start, written after ``E``.

    Returns
    -------
    dict
        ``retried`` (indices of the starts that needed more than one attempt)
        and ``start_outcomes`` (one row per start; from a ``StoredResults`` a
        :class:`~youbot_opt.cli.output.StreamedList` that reads the journal again
        each time it is iterated, so ``summary.json`` and ``--json`` write the
        rows one at a time and a sweep of a million starts does not hold them).
    """
    from youbot_opt.cli.output import StreamedList
    from youbot_opt.ikpath.stored import StoredResults

    def row(index: int, status: str, r: Any, attempts: int | None) -> dict[str, Any]:  # noqa: ANN401
        return {
            "index": index,
            "status": status,
            "E": r.objective,
            **({} if detail is None else detail(r)),
            "attempts": attempts,
            "message": None if r.success else r.message,
        }

    if isinstance(results, StoredResults):  # streamed from the journal, never all in memory
        stored = results

        def rows() -> Iterator[dict[str, Any]]:
            return (row(s.index, s.status, s, s.attempts) for s in stored.summaries())

        retried = [s.index for s in stored.summaries() if s.attempts > 1]
        return {"retried": retried, "start_outcomes": StreamedList(rows, len(stored))}
    return {
        "retried": [i for i, a in enumerate(attempts) if a > 1],
        "start_outcomes": [
            row(i, r.status.value, r, attempts[i] if attempts else None)
            for i, r in enumerate(results)
        ],
    }


def print_starts(doc: dict[str, Any]) -> None:
    """Print how the starts ran: throughput and outcomes, resumed, retried and crashed starts.

    ``doc`` is the run's summary (``starts``, ``seed``, ``start_kind``,
    ``workers``, ``wall_time`` [s], ``starts_per_second`` [1/s],
    ``status_counts``, ``resumed`` and the fields of :func:`start_fields`).
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
    for o in doc["start_outcomes"]:
        if o["status"] == "crashed":
            print(f"  start {o['index']} failed after {o['attempts']} attempts: {o['message']}")
