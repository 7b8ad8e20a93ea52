"""The best iterate of a failed IK-path solve (both methods).

A failed solve (iteration cap, stall, local infeasibility) returns the best
configurations the method visited rather than the last ones, ranked as in
:mod:`youbot_opt.nlp.best_iterate`: among iterates meeting the targets to
``constraint_tol``, the lowest E; otherwise the smallest constraint
violation ``max |F(q_j) - p_j|`` (recomputed with Pinocchio; with a
clearance, also the rows' shortfall below the margin). Joint limits
need no ranking: both methods' iterates lie inside them (IPOPT's after
projection onto the box).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.nlp.best_iterate import Iterate, best_of

__all__ = ["rank", "pick_best"]


def rank(problem: CyclicIKProblem, x: Array, iteration: int) -> Iterate:
    """Rank configurations ``x`` [rad]: E [rad^2] and ``max |F(q_j) - p_j|`` [m] (Pinocchio).

    With a clearance the violation is the larger of that and the clearance rows'
    largest shortfall below the margin [m] (:class:`~youbot_opt.ikpath.clearance.IKClearance`).

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem (its targets and kinematics).
    x : ndarray, shape (s * n,)
        Configurations in [rad].
    iteration : int
        Iteration number (-1 for the final iterate).

    Returns
    -------
    Iterate
        With empty multiplier arrays.
    """
    empty = np.zeros(0)
    violation = float(np.max(np.abs(problem.constraints(x))))
    rows = problem.clearance_rows
    if rows is not None and rows.labels:
        violation = max(violation, float(np.max(rows.spec.margin - rows.rows(x))))
    return Iterate(x, empty, empty, problem.objective(x), violation, iteration)


def pick_best(
    problem: CyclicIKProblem,
    final: Array,
    visited: Iterable[Array],
    constraint_tol: float,
) -> tuple[Array, str]:
    """Return the best of ``final`` and the ``visited`` iterates, with a note if not ``final``.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem (its targets and kinematics rank the iterates).
    final : ndarray, shape (s * n,)
        The configurations the method ended with, in [rad].
    visited : iterable of ndarray
        Earlier iterates (flattened configurations in [rad]) in order; their
        index is the iteration number in the note.
    constraint_tol : float
        Target tolerance in [m] that makes an iterate feasible.

    Returns
    -------
    x : ndarray
        The best configurations (``final`` itself when nothing beats it).
    note : str
        Empty, or which iterate was returned instead of the last one and why.
    """
    last = rank(problem, final, -1)
    count = 0

    def ranked() -> Iterator[Iterate]:
        nonlocal count
        for k, x in enumerate(visited):
            count += 1
            x = np.asarray(x, dtype=float).ravel()
            if np.all(np.isfinite(x)):
                yield rank(problem, x, k)

    best = best_of(last, ranked(), constraint_tol)
    if best is last:
        return final, ""
    note = (
        f"returned the best iterate, {best.iteration} of {count - 1} (|c| = "
        f"{best.violation:.3g} m, E = {best.objective:.6g} rad^2), not the last (|c| = "
        f"{last.violation:.3g} m, E = {last.objective:.6g} rad^2); multipliers are the last "
        "iterate's estimates"
    )
    return best.x.copy(), note
