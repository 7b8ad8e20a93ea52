"""The starts of an IK multistart run with ``keep_results=False``: summaries, read on demand.

Owns :class:`StartSummary` (one start's figures, read from the sweep journal),
:func:`closest_start` (the fallback best, found in one streamed pass),
:class:`StoredResults` (the full results as a sequence that loads each from the
output folder when asked for) and :class:`ClusterIndices` (the start
indices of one distinct minimum, read from the optima members table). The
driver holds none of them per start; :mod:`youbot_opt.ikpath.sweep` makes them.

    ms.results[17]            # loaded from the output folder (not held)
    ms.minima[0].start_indices[:5]
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, replace
from typing import Generic, TypeVar

from youbot_opt._checks import to_float, to_int
from youbot_opt.sweeps.lazy import LazySequence, ListEquality
from youbot_opt.sweeps.multistart import LazyStarts
from youbot_opt.sweeps.optima import KeepRule
from youbot_opt.sweeps.selection import Clusters, stream_optima

__all__ = ["ClusterIndices", "StartSummary", "StoredResults", "closest_start"]

R = TypeVar("R")


@dataclass(frozen=True, slots=True, kw_only=True)
class StartSummary(Generic[R]):
    """One start's figures as its sweep journal holds them (its result only if kept).

    Attributes
    ----------
    index : int
        Start index (0 = the zero vector or the greedy path).
    status : str
        Status value (``"solved"``, ``"max_iter"``, ``"crashed"``, ...).
    success : bool
        Whether the start met the targets (within tolerance).
    objective : float
        ``E`` in [rad^2] (NaN if not finite).
    max_residual : float
        Planar: largest constraint residual ``|c_i|`` in [m]; spatial: largest
        position error in [m] (``inf`` if not finite).
    max_orientation_error : float
        Spatial: largest orientation error in [rad]; planar: 0.
    iterations : int
        Iterations of the solve.
    solve_time : float
        Wall time of the solve in [s].
    attempts : int
        Attempts made, earlier runs on the same output included.
    message : str or None
        Why a start that did not succeed failed (``None`` on success).
    result : IKPathResult or None
        The full result, for the kept starts only (best and distinct minima).
    """

    index: int
    status: str
    success: bool
    objective: float
    max_residual: float
    max_orientation_error: float
    iterations: int
    solve_time: float
    attempts: int
    message: str | None = None
    result: R | None = None

    @classmethod
    def from_record(cls, summary: Mapping[str, object], attempts: int) -> StartSummary[R]:
        """Build from a journal line's summary (planar or spatial figures)."""

        def num(x: object, missing: float) -> float:
            return missing if x is None else to_float(x)

        residual = summary.get("max_residual", summary.get("max_position_error"))
        message = summary.get("message")
        return cls(
            index=to_int(summary["index"]),
            status=str(summary["status"]),
            success=bool(summary["success"]),
            objective=num(summary.get("objective"), math.nan),
            max_residual=num(residual, math.inf),
            max_orientation_error=num(summary.get("max_orientation_error"), 0.0),
            iterations=to_int(summary["iterations"]),
            solve_time=to_float(summary["wall_time_s"]),
            attempts=int(attempts),
            message=None if message is None else str(message),
        )

    def with_result(self, result: R) -> StartSummary[R]:
        """Return the same start holding its full result."""
        return replace(self, result=result)

    @property
    def miss(self) -> float:
        """How far the start is from meeting the targets: the fallback best's rank.

        Largest position error plus largest orientation error (0 on the
        planar methods), the measure ``MultistartResult.best`` ranks by when
        nothing succeeded.
        """
        return self.max_residual + self.max_orientation_error


def closest_start(summaries: Iterable[StartSummary[R]]) -> int:
    """Return the index of the start closest to meeting the targets, in one pass.

    Smallest :attr:`StartSummary.miss`, then smallest ``E``, then the first
    (lowest index), as ``min`` over the results in start order finds it: the
    best when nothing succeeded (0 if there is no start).
    """
    best: tuple[float, ...] | None = None
    closest = 0
    for s in summaries:
        rank = (s.miss, s.objective)
        if best is None or rank < best:
            best, closest = rank, s.index
    return closest


class StoredResults(LazyStarts[R]):
    """The full results of a ``keep_results=False`` multistart, loaded when asked for.

    ``results[i]`` is the kept result of start ``i`` (best and distinct
    minima, held), else loaded from the output folder (a start that failed
    every attempt is rebuilt as its ``CRASHED`` result). Nothing per start is
    held; valid while the output folder is there.

    Parameters
    ----------
    n_starts : int
        Number of starts.
    load : callable ``(i) -> result``
        Start ``i``'s full result from the folder.
    summary : callable ``(i) -> StartSummary``
        Start ``i``'s figures from the journal.
    kept : mapping of int to result
        The results held in memory, by start index.
    items : mapping of str to StartSummary
        The sweep's items by key, in start order (for :meth:`cluster`).
    full : callable ``(key) -> StartSummary``
        An item with its full result (for :meth:`cluster`).
    """

    def __init__(
        self,
        n_starts: int,
        *,
        load: Callable[[int], R],
        summary: Callable[[int], StartSummary[R]],
        kept: Mapping[int, R],
        items: Mapping[str, StartSummary[R]],
        full: Callable[[str], StartSummary[R]],
    ) -> None:
        held = dict(kept)
        super().__init__(n_starts, lambda j: held[j] if j in held else load(j))
        self._summary, self._kept = summary, held
        self._items, self._full = items, full

    def index(self, value: object, start: int = 0, stop: int | None = None) -> int:
        """Start index of a kept result (identity), else a search through the folder."""
        for j, r in self._kept.items():
            if r is value and start <= j < (len(self) if stop is None else stop):
                return j
        return super().index(value, start, len(self) if stop is None else stop)

    @property
    def held(self) -> int:
        """Number of full results held in memory (the distinct minima's)."""
        return len(self._kept)

    def summary(self, i: int) -> StartSummary[R]:
        """Start ``i``'s figures from the journal (no result loaded)."""
        return self._summary(i)

    def summaries(self) -> Iterator[StartSummary[R]]:
        """Every start's figures in start order, read one at a time from the journal."""
        return (self._summary(i) for i in range(len(self)))

    def cluster(
        self, rule: KeepRule[StartSummary[R]]
    ) -> tuple[dict[str, StartSummary[R]], Clusters]:
        """Choose the distinct minima again with ``rule``, streamed from the folder.

        Loads each converged start's result once, one at a time
        (:func:`~youbot_opt.sweeps.selection.stream_optima`); returns the
        representatives (full) by key and the clusters.
        """
        return stream_optima(self._items, rule, self._full)

    def __repr__(self) -> str:
        return f"StoredResults({len(self)} starts, {len(self._kept)} held)"


class ClusterIndices(ListEquality, LazySequence[int]):
    """Start indices of one distinct minimum, read from the optima members table.

    Parameters
    ----------
    clusters : Clusters
        The sweep's distinct minima.
    number : int
        Which minimum.
    index_of : callable ``(key) -> int``
        Start index of an item key.
    sorted_order : bool
        Ascending start indices (keys are fixed-width, so key order is index
        order); else cluster order (representative first, then by ``E``).
    """

    def __init__(
        self, clusters: Clusters, number: int, index_of: Callable[[str], int], *, sorted_order: bool
    ) -> None:
        self._clusters, self._number, self._index_of = clusters, number, index_of
        self._sorted = sorted_order

    def __len__(self) -> int:
        return self._clusters.counts[self._number]

    def ascending(self) -> ClusterIndices:
        """Return the same start indices in ascending order."""
        return ClusterIndices(self._clusters, self._number, self._index_of, sorted_order=True)

    def __iter__(self) -> Iterator[int]:
        keys = (
            self._clusters.members_in_key_order(self._number)
            if self._sorted
            else iter(self._clusters[self._number])
        )
        return (self._index_of(k) for k in keys)

    def _slice(self, s: slice) -> list[int]:
        return list(self)[s]  # one pass over the table

    def _index_error(self, i: int, n: int) -> str:
        return f"minimum {self._number} has {n} start(s), got index {i}"

    def _item(self, j: int) -> int:
        if j == 0 and not self._sorted:
            return self._index_of(self._clusters.representatives[self._number])
        return next(itertools.islice(iter(self), j, None))

    def __repr__(self) -> str:
        return f"ClusterIndices({len(self)} starts)"
