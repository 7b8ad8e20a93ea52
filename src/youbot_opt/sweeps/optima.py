"""The distinct local optima of a sweep: greedy grouping by objective and a distance.

The one rule by which every multistart groups its converged solves into
distinct local optima: items in order of increasing objective, each joining the
first cluster whose representative is within ``obj_tol`` (relative) in
objective and ``dist_tol`` in the caller's ``distance`` (:func:`cluster_optima`);
:func:`select_optima` applies it to a ``keep_results=False`` sweep, loading one
full item at a time. Each caller keeps its own distance and default tolerances,
named ``obj_tol`` and ``dist_tol`` everywhere, finite and > 0 (:func:`check_tolerances`).

    clusters = cluster_optima(results, objective=lambda r: r.objective,
                              distance=my_distance, obj_tol=1e-6, dist_tol=1e-3)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Generic, TypeVar

from youbot_opt.exceptions import ParameterError

__all__ = ["KeepRule", "check_tolerances", "cluster_optima", "select_optima"]

T = TypeVar("T")


def check_tolerances(obj_tol: float, dist_tol: float) -> tuple[float, float]:
    """Return the clustering tolerances as floats if both are finite and > 0.

    A zero tolerance is refused: with ``dist_tol = 0`` every item would be its
    own optimum unless bitwise equal to a representative (and ``obj_tol = 0``
    likewise in objective), which no solver's output is.

    Parameters
    ----------
    obj_tol : float
        Relative objective tolerance (dimensionless):
        ``|f - f_c| <= obj_tol max(1, |f_c|)``.
    dist_tol : float
        Distance tolerance, in the unit of the caller's distance ([rad] for
        the trajectory and IK-path distances).

    Returns
    -------
    tuple of float
        ``(obj_tol, dist_tol)``.

    Raises
    ------
    ParameterError
        Naming the first bad tolerance (``name`` ``"obj_tol"`` or ``"dist_tol"``,
        its ``value``) if it is not a finite number > 0 (zero, negative, NaN,
        infinite, a bool or not a number).
    """
    checked = []
    for name, tol in (("obj_tol", obj_tol), ("dist_tol", dist_tol)):
        try:
            value = float(tol)
        except (TypeError, ValueError):
            value = math.nan
        if isinstance(tol, bool) or not (math.isfinite(value) and value > 0):
            raise ParameterError(
                f"{name} must be a finite number > 0, got {tol!r}", name=name, value=tol
            )
        checked.append(value)
    return checked[0], checked[1]


@dataclass(frozen=True, slots=True, kw_only=True)
class KeepRule(Generic[T]):
    """What a sweep run with ``keep_results=False`` keeps in memory: the distinct optima.

    Attributes
    ----------
    objective : callable ``(item) -> float or None``
        Objective of a converged item, from its light form (summary);
        ``None`` (or NaN) for an item that did not converge.
    distance : callable ``(a, b) -> float`` or None
        Distance of two full items, in the unit of ``dist_tol``; ``None``
        keeps only the best item (one cluster, no item loaded but the best;
        the tolerances are then unused).
    obj_tol, dist_tol : float
        The tolerances of :func:`cluster_optima` (the caller's defaults);
        with a ``distance``, both finite and > 0 (:func:`check_tolerances`,
        checked when the rule is made).
    group : callable ``(item) -> hashable``, optional
        Items of different groups are never clustered together (e.g. the
        bound scales of a bound-scaling study: the best of each is kept).
    """

    objective: Callable[[T], float | None]
    distance: Callable[[T, T], float] | None = None
    obj_tol: float = 0.0
    dist_tol: float = 0.0
    group: Callable[[T], Hashable] | None = None

    def __post_init__(self) -> None:
        if self.distance is not None:
            check_tolerances(self.obj_tol, self.dist_tol)


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
        Relative objective tolerance (dimensionless, finite, > 0):
        ``|f - f_c| <= obj_tol max(1, |f_c|)``.
    dist_tol : float
        Largest ``distance`` to a cluster's representative (finite, > 0).

    Returns
    -------
    list of list
        Clusters in order of their representatives' objectives, each with its
        lowest-objective member first; ties keep the order of ``items``
        (the sort is stable).

    Raises
    ------
    ParameterError
        If a tolerance is not finite and > 0 (:func:`check_tolerances`).
    """
    check_tolerances(obj_tol, dist_tol)
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


def select_optima(
    items: Mapping[str, T], rule: KeepRule[T], load: Callable[[str], T]
) -> tuple[dict[str, T], list[list[str]]]:
    """Cluster items as :func:`cluster_optima` does, loading full items only where needed.

    Items are taken by increasing ``rule.objective`` (ties in the order of
    ``items``). An item is loaded only if it starts a cluster or lies within
    ``obj_tol`` of a representative (a distance is needed); only the
    representatives stay loaded, so memory does not grow with the items.

    Parameters
    ----------
    items : mapping of str to item
        Light items (their summaries), by key.
    rule : KeepRule
        Objective, distance and tolerances (checked when the rule was made).
    load : callable ``(key) -> item``
        The full item of a key (e.g. from the sweep's store).

    Returns
    -------
    tuple of (dict, list of list of str)
        The full representatives by key (lowest objective first, so the first
        is the best item), and the clusters as keys, each representative first
        (with ``rule.group``: group after group, in order of first appearance).
    """
    if rule.group is not None:
        groups: dict[Hashable, dict[str, T]] = {}
        for key, item in items.items():
            groups.setdefault(rule.group(item), {})[key] = item
        whole = replace(rule, group=None)
        kept_all: dict[str, T] = {}
        clusters_all: list[list[str]] = []
        for members in groups.values():
            part = select_optima(members, whole, load)
            kept_all.update(part[0])
            clusters_all += part[1]
        return kept_all, clusters_all
    ranked: list[tuple[float, str]] = []
    for key, item in items.items():
        f = rule.objective(item)
        if f is not None and not math.isnan(f):
            ranked.append((float(f), key))
    ranked.sort(key=lambda fk: fk[0])  # stable: ties keep the order of items
    reps: list[tuple[float, T]] = []
    clusters: list[list[str]] = []
    kept: dict[str, T] = {}
    if rule.distance is None:  # the best only
        if not ranked:
            return {}, []
        best = ranked[0][1]
        return {best: load(best)}, [[key for _, key in ranked]]
    for f, key in ranked:
        near = [
            i
            for i, (f_rep, _) in enumerate(reps)
            if abs(f - f_rep) <= rule.obj_tol * max(1.0, abs(f_rep))
        ]
        full = load(key)
        for i in near:
            if rule.distance(full, reps[i][1]) <= rule.dist_tol:
                clusters[i].append(key)
                break
        else:
            reps.append((f, full))
            clusters.append([key])
            kept[key] = full
    return kept, clusters
