"""The best iterate of a failed IK-path solve (both methods).

A failed solve (iteration cap, stall, local infeasibility) returns the best
configurations the method visited rather than the last ones, ranked as in
:mod:`youbot_opt.nlp.best_iterate`: among iterates meeting the targets to
``constraint_tol``, the lowest E; otherwise the smallest constraint
violation ``max |F(q_j) - p_j|`` (recomputed with Pinocchio). Joint limits
need no ranking: both methods' iterates lie inside them (IPOPT's after
projection onto the box).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.nlp.best_iterate import Iterate, better
from youbot_opt.ikpath.problem import CyclicIKProblem

__all__ = ["pick_best"]


def _rank(problem: CyclicIKProblem, x: Array, iteration: int) -> Iterate:
    empty = np.zeros(0)
    violation = float(np.max(np.abs(problem.constraints(x))))
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
    best = _rank(problem, final, -1)
    last = best
    count = 0
    for k, x in enumerate(visited):
        count += 1
        x = np.asarray(x, dtype=float).ravel()
        if not np.all(np.isfinite(x)):
            continue
        candidate = _rank(problem, x, k)
        if not (np.isfinite(candidate.objective) and np.isfinite(candidate.violation)):
            continue
        if better(candidate, best, constraint_tol):
            best = candidate
    if best is last:
        return final, ""
    note = (
        f"returned the best iterate, {best.iteration} of {count - 1} (|c| = "
        f"{best.violation:.3g} m, E = {best.objective:.6g} rad^2), not the last (|c| = "
        f"{last.violation:.3g} m, E = {last.objective:.6g} rad^2); multipliers are the last "
        "iterate's estimates"
    )
    return best.x.copy(), note
