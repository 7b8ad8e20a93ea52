"""Starts of a ``keep_results=False`` trajectory sweep, read from its folder when asked for.

Owns the lazy sequences a lean :class:`~youbot_opt.trajopt.multistart.MultistartResult`
holds instead of its starts: :class:`StoredStarts` (every start), :class:`OptimumMembers`
(the members of one distinct optimum, by their keys in the sweep's optima table)
and :class:`ConvergedStarts` (counted once, read when iterated). Each equals a
tuple of the same starts; none holds a start it was not given.

    ms.starts[7]            # a StoredStarts: start 7's figures, read from the journal
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Mapping, Sequence

from youbot_opt.sweeps.lazy import LazySequence, ListEquality
from youbot_opt.trajopt.sweep import StartJobs, StartOutcome

__all__ = ["ConvergedStarts", "OptimumMembers", "StoredStarts"]


class _LazyStarts(ListEquality, LazySequence[StartOutcome]):
    """A sequence of starts read on demand, equal to a tuple of the same starts."""

    noun = "start"

    def _slice(self, s: slice) -> tuple[StartOutcome, ...]:
        return tuple(self._item(j) for j in range(len(self))[s])


class StoredStarts(_LazyStarts):
    """The starts of a ``keep_results=False`` multistart, read from its folder when asked for.

    Start ``i`` is ``outcomes[jobs[i].key]`` each time (its figures from the
    sweep's journal; the kept optima in full), so a result of 10^5 starts
    holds no start. Valid while the output folder is there.
    """

    def __init__(self, jobs: StartJobs, outcomes: Mapping[str, StartOutcome]) -> None:
        self._jobs, self._outcomes = jobs, outcomes

    def __len__(self) -> int:
        return len(self._jobs)

    def _item(self, j: int) -> StartOutcome:
        return self._outcomes[self._jobs[j].key]

    def __repr__(self) -> str:
        return f"StoredStarts({len(self)} starts)"


class OptimumMembers(_LazyStarts):
    """The members of one optimum of a ``keep_results=False`` multistart, by their keys.

    ``keys`` is the cluster from the sweep's optima table (its length is the
    stored count, a member key is one indexed read); each start is read from
    ``starts`` (the sweep's outcomes) when asked for.
    """

    def __init__(self, keys: Sequence[str], starts: Mapping[str, StartOutcome]) -> None:
        self._keys, self._starts = keys, starts

    def __len__(self) -> int:
        return len(self._keys)

    def _item(self, j: int) -> StartOutcome:
        return self._starts[self._keys[j]]

    def __iter__(self) -> Iterator[StartOutcome]:
        return (self._starts[k] for k in self._keys)

    def __repr__(self) -> str:
        return f"<{len(self)} member start(s), read from the output folder>"


class ConvergedStarts(_LazyStarts):
    """Converged starts of a ``keep_results=False`` multistart: counted once, read when iterated.

    ``len`` is the count of the sweep's tally; iterating reads every start
    once from the folder (nothing is held); indexing scans up to the index.
    """

    def __init__(self, starts: Sequence[StartOutcome], count: int) -> None:
        self._starts, self._count = starts, count

    def __len__(self) -> int:
        return self._count

    def __iter__(self) -> Iterator[StartOutcome]:
        return (s for s in self._starts if s.success)

    noun = "converged start"

    def _item(self, j: int) -> StartOutcome:
        return next(itertools.islice(iter(self), j, None))

    def __repr__(self) -> str:
        return f"<{len(self)} converged start(s), read from the output folder>"
