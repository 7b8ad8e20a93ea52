"""What every multistart knows of its starts, generic over the optimiser's start type.

Owns :class:`StartTally` (the counts of a ``keep_results=False`` multistart,
computed once at its end, with what the optimiser found on the same pass) and
:func:`tally_starts`. The trajectory and IK-path multistarts both hold one;
what differs (trajopt: the distinct optima; ikpath: the start closest to the
targets) is the tally's ``found``.

    tally = tally_starts([("solved", True), ("max_iter", False)], found=0)
    tally.n_converged, tally.status_counts   # 1, {'solved': 1, 'max_iter': 1}
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Generic, TypeVar

__all__ = ["StartTally", "tally_starts"]

F = TypeVar("F")


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
