"""Greedy clustering of local optima by objective and a distance, knowing nothing of robots.

Owns the one rule by which every multistart groups its converged solves into
distinct local optima (trajectory multistart, IK-path multistart, the study's
vertex-LP search): items are taken in order of increasing objective; each
joins the first cluster whose representative (its first, lowest member) is
within ``obj_tol`` in objective, relative (``|f - f_c| <= obj_tol max(1,
|f_c|)``), and within ``dist_tol`` in the caller's ``distance``; otherwise it
starts a new cluster. Each caller keeps its own tolerances and distance.

    clusters = cluster_optima(results, objective=lambda r: r.objective,
                              distance=my_distance, obj_tol=1e-6, dist_tol=1e-3)
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TypeVar

from youbot_opt.exceptions import ParameterError

__all__ = ["cluster_optima"]

T = TypeVar("T")


def cluster_optima(
    items: Iterable[T],
    *,
    objective: Callable[[T], float],
    distance: Callable[[T, T], float],
    obj_tol: float,
    dist_tol: float,
) -> list[list[T]]:
    """Group items (converged solves) into distinct local optima, lowest objective first.

    Parameters
    ----------
    items : iterable
        The items to cluster (the caller filters out failed solves).
    objective : callable ``(item) -> float``
        The objective to compare, in the caller's unit.
    distance : callable ``(a, b) -> float``
        Distance of two items, in the unit of ``dist_tol`` (e.g. [rad]).
    obj_tol : float
        Relative objective tolerance (>= 0): ``|f - f_c| <= obj_tol max(1, |f_c|)``.
    dist_tol : float
        Largest ``distance`` to a cluster's representative (>= 0).

    Returns
    -------
    list of list
        Clusters in order of their representatives' objectives, each with its
        lowest-objective member first; ties keep the order of ``items``
        (the sort is stable).

    Raises
    ------
    ParameterError
        If a tolerance is negative or NaN.
    """
    if not (obj_tol >= 0 and dist_tol >= 0):
        raise ParameterError(
            f"obj_tol and dist_tol must be >= 0, got {obj_tol!r}, {dist_tol!r}", name="obj_tol"
        )
    clusters: list[list[T]] = []
    for item in sorted(items, key=objective):
        f = objective(item)
        for members in clusters:
            f_rep = objective(members[0])
            if abs(f - f_rep) > obj_tol * max(1.0, abs(f_rep)):
                continue
            if distance(item, members[0]) <= dist_tol:
                members.append(item)
                break
        else:
            clusters.append([item])
    return clusters
