"""One multistart result and one local optimum, generic over the optimiser's start type.

Owns :class:`Multistart` (what every multistart result answers: counts, success
rate, converged starts, status counts), :class:`LocalOptimum` (a cluster of
converged starts), :class:`StartTally` with :func:`tally_starts` (the counts of a
``keep_results=False`` run, made once at its end) and the lazy views
:class:`LazyStarts`, :class:`OptimumMembers`, :class:`ConvergedStarts`. The trajectory
and IK-path results specialise :class:`Multistart`; what differs is theirs.

    tally = tally_starts([("solved", True), ("max_iter", False)], found=0)
    tally.n_converged, tally.status_counts   # 1, {'solved': 1, 'max_iter': 1}
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar, Generic, Protocol, TypeVar

from youbot_opt._typing import JSONDict
from youbot_opt.sweeps.lazy import LazySequence, ListEquality

__all__ = [
    "ConvergedStarts",
    "LazyStarts",
    "LocalOptimum",
    "Multistart",
    "OptimumMembers",
    "Start",
    "StartTally",
    "tally_starts",
]

F = TypeVar("F")
K = TypeVar("K")
T = TypeVar("T")


class Start(Protocol):
    """What a multistart needs of one start: whether it converged, and its objective."""

    @property
    def success(self) -> bool:
        """Whether the start's solve succeeded."""
        ...

    @property
    def objective(self) -> float:
        """The start's objective, in the optimiser's unit."""
        ...


S = TypeVar("S", bound=Start)


@dataclass(frozen=True, slots=True, kw_only=True)
class StartTally(Generic[F]):
    """What a ``keep_results=False`` multistart knows of all its starts, counted once.

    The accessors of a multistart result answer from it in time and memory of
    the number of optima, not of starts.

    Attributes
    ----------
    n_starts : int
        Number of starts counted.
    n_converged : int
        Number of starts whose solve succeeded.
    status_counts : mapping of str to int
        Number of starts per status.
    found : F
        What the optimiser found on the same pass: trajopt the distinct optima
        at the default tolerances (best first); ikpath the index of the start
        closest to meeting the targets (the best when none succeeded).
    """

    n_starts: int
    n_converged: int
    status_counts: Mapping[str, int]
    found: F


def tally_starts(
    outcomes: Iterable[tuple[str, bool]], *, found: F, by_status: bool = False
) -> StartTally[F]:
    """Count the starts' statuses and successes in one pass.

    Parameters
    ----------
    outcomes : iterable of (str, bool)
        Each start's status and whether it succeeded, read once.
    found : F
        The optimiser's own figure, held as :attr:`StartTally.found`.
    by_status : bool
        Order :attr:`StartTally.status_counts` by status (else by first appearance).

    Returns
    -------
    StartTally
    """
    n = ok = 0
    counts: dict[str, int] = {}
    for status, success in outcomes:
        n += 1
        ok += bool(success)
        counts[status] = counts.get(status, 0) + 1
    if by_status:
        counts = dict(sorted(counts.items()))
    return StartTally(n_starts=n, n_converged=ok, status_counts=counts, found=found)


@dataclass(frozen=True, slots=True, kw_only=True)
class LocalOptimum(Generic[S]):
    """A cluster of converged starts that reached the same local optimum.

    Attributes
    ----------
    members : sequence of S
        The member starts, the representative (lowest objective) first, then by
        objective: a tuple, or with ``keep_results=False`` an
        :class:`OptimumMembers` reading each member when asked for.
    n_starts : int
        Number of starts of the multistart (for :attr:`fraction`).
    """

    members: Sequence[S]
    n_starts: int

    @property
    def best(self) -> S:
        """The representative: the lowest member."""
        return self.members[0]

    @property
    def objective(self) -> float:
        """Lowest objective among the members."""
        return self.best.objective

    @property
    def count(self) -> int:
        """Number of member starts."""
        return len(self.members)

    @property
    def fraction(self) -> float:
        """``count`` over the number of starts of the multistart."""
        return self.count / max(self.n_starts, 1)

    @property
    def objective_spread(self) -> float:
        """Largest objective minus smallest among the members (reads the last member)."""
        return self.members[-1].objective - self.best.objective

    def summary(self) -> JSONDict:
        """JSON-ready figures: objective, count, fraction, objective spread."""
        return {
            "objective": self.objective,
            "count": self.count,
            "fraction": self.fraction,
            "objective_spread": self.objective_spread,
        }


class Multistart(Generic[S, F]):
    """What every multistart result answers, from its starts or from its tally.

    A specialisation is a frozen dataclass holding its starts (:meth:`_starts`)
    and a ``tally`` (``None`` when the starts are held; with ``keep_results=False``
    the counts, made once at the end, so nothing here reads a start), and gives
    :attr:`best` and ``distinct_optima``.
    """

    __slots__ = ()

    tally: StartTally[F] | None
    statuses_sorted: ClassVar[bool] = False
    """Whether :meth:`status_counts` is ordered by status (else by first appearance)."""

    def _starts(self) -> Sequence[S]:
        """Every start, in start order."""
        raise NotImplementedError

    @staticmethod
    def _status(start: S) -> str:
        """Return the status value of a start."""
        raise NotImplementedError

    @property
    def n_starts(self) -> int:
        """Number of starts."""
        return len(self._starts())

    @property
    def n_converged(self) -> int:
        """Number of starts whose solve succeeded."""
        if self.tally is not None:
            return self.tally.n_converged
        return sum(s.success for s in self._starts())

    @property
    def success_rate(self) -> float:
        """Fraction of starts that converged (0 if there are none)."""
        return self.n_converged / self.n_starts if self.n_starts else 0.0

    @property
    def converged(self) -> Sequence[S]:
        """Starts whose solve succeeded, in start order.

        A tuple; with a tally a :class:`ConvergedStarts` of the counted length
        that reads the starts as it is iterated (nothing held).
        """
        if self.tally is not None:
            return ConvergedStarts(self._starts(), self.tally.n_converged)
        return tuple(s for s in self._starts() if s.success)

    def status_counts(self) -> dict[str, int]:
        """Return the number of starts per status."""
        if self.tally is not None:
            return dict(self.tally.status_counts)
        outcomes = ((self._status(s), s.success) for s in self._starts())
        return dict(
            tally_starts(outcomes, found=None, by_status=self.statuses_sorted).status_counts
        )


class LazyStarts(ListEquality, LazySequence[T]):
    """Per-start items of a lean multistart, read when asked for: item ``j`` is ``read(j)``.

    The starts, their results or their attempt counts: nothing per start is
    held; equal to a tuple of the same items (a slice is a tuple). Valid while
    the output folder is there.
    """

    noun = "start"

    def __init__(self, n: int, read: Callable[[int], T]) -> None:
        self._n, self._read = n, read

    def __len__(self) -> int:
        return self._n

    def _item(self, j: int) -> T:
        return self._read(j)

    def _slice(self, s: slice) -> tuple[T, ...]:
        return tuple(self._item(j) for j in range(len(self))[s])


class OptimumMembers(LazyStarts[S], Generic[K, S]):
    """The members of one optimum of a ``keep_results=False`` multistart, by their keys.

    ``keys`` is the cluster (from the sweep's optima table: its length is the
    stored count, a member key one indexed read); member ``j`` is
    ``read(keys[j])``, read when asked for.
    """

    def __init__(self, keys: Sequence[K], read: Callable[[K], S]) -> None:
        super().__init__(len(keys), lambda j: read(keys[j]))
        self._keys: Sequence[K] = keys
        self._by_key: Callable[[K], S] = read

    def __iter__(self) -> Iterator[S]:
        return (self._by_key(k) for k in self._keys)

    def __repr__(self) -> str:
        return f"<{len(self)} member start(s), read from the output folder>"


class ConvergedStarts(LazyStarts[S]):
    """Converged starts of a ``keep_results=False`` multistart: counted once, read when iterated.

    ``len`` is the count of the run's tally; iterating reads every start once
    (nothing is held); indexing scans up to the index.
    """

    noun = "converged start"

    def __init__(self, starts: Sequence[S], count: int) -> None:
        super().__init__(count, lambda j: next(itertools.islice(iter(self), j, None)))
        self._starts = starts

    def __iter__(self) -> Iterator[S]:
        return (s for s in self._starts if s.success)

    def __repr__(self) -> str:
        return f"<{len(self)} converged start(s), read from the output folder>"
