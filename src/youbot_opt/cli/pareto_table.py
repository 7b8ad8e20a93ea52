"""The printed table and JSON summary of ``youbot-opt pareto``, with distinct points counted.

Several weights can give the same solution (at the high-beta end of the study-1
front, beta = 0.85, 0.90 and 0.95 all give T = 1.3611 s, W = 16.3490 N^2 m^2 s).
Such weights are one point of the front: two converged points whose duration T
and work W agree within a relative tolerance are counted once, and the table
says which weights map to each distinct point.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from youbot_opt._typing import JSONDict
from youbot_opt.trajopt.pareto import ParetoFront, ParetoPoint

__all__ = ["DISTINCT_RTOL", "distinct_points", "pareto_summary", "pareto_table", "table_number"]

DISTINCT_RTOL = 1e-6
"""Relative tolerance on T and W under which two points are the same point (IPOPT tol 1e-8)."""


def _same(a: float, b: float, rtol: float) -> bool:
    return abs(a - b) <= rtol * max(abs(a), abs(b), 1e-300)


def distinct_points(
    points: Sequence[ParetoPoint], rtol: float = DISTINCT_RTOL
) -> list[list[ParetoPoint]]:
    """Group the converged, non-dominated points whose T and W agree within ``rtol``.

    Parameters
    ----------
    points : sequence of ParetoPoint
        The sweep's points (``duration`` in [s], ``work`` in [N^2 m^2 s]), any order.
    rtol : float
        Relative tolerance on both T and W.

    Returns
    -------
    list of list of ParetoPoint
        One group per distinct point, in increasing beta (of each group's first weight);
        each group's weights in increasing beta.
    """
    keep = [p for p in points if p.success and not p.dominated]
    keep.sort(key=lambda p: (p.duration, p.work, p.beta))
    groups: list[list[ParetoPoint]] = []
    for p in keep:
        for group in groups:
            q = group[0]
            if _same(p.duration, q.duration, rtol) and _same(p.work, q.work, rtol):
                group.append(p)
                break
        else:
            groups.append([p])
    for group in groups:
        group.sort(key=lambda p: p.beta)
    return sorted(groups, key=lambda g: g[0].beta)


def table_number(x: float, spec: str) -> str:
    """Return a number as a sweep table prints it: ``format(x, spec)``, or ``-`` if not finite.

    Parameters
    ----------
    x : float
        The value, in its column's unit (e.g. T in [s], W in [N^2 m^2 s]); NaN
        or infinite for a solve that did not converge.
    spec : str
        Format specification (e.g. ``".4f"``).

    Returns
    -------
    str
        The cell's text, without padding.
    """
    return format(x, spec) if math.isfinite(x) else "-"


def pareto_table(front: ParetoFront, rtol: float = DISTINCT_RTOL) -> list[str]:
    """Return the lines of the printed Pareto table.

    Parameters
    ----------
    front : ParetoFront
        The sweep's result.
    rtol : float
        Relative tolerance on T and W of :func:`distinct_points`.

    Returns
    -------
    list of str
        A headline (weights, distinct non-dominated points, resumed, wall time), the
        table (one row per weight, with the number of its distinct point) and one line
        per distinct point reached by several weights.
    """
    groups = distinct_points(front.points, rtol)
    number = {id(p): k + 1 for k, group in enumerate(groups) for p in group}
    n_nondominated = sum(len(g) for g in groups)
    lines = [
        f"pareto: {len(front.points)} weights, {n_nondominated} non-dominated, "
        f"{len(groups)} distinct points (equal T and W within {rtol:g} relative are one "
        f"point), {front.resumed} resumed, {front.wall_time:.2f} s",
        f"{'beta':>6} {'T [s]':>9} {'W [N^2 m^2 s]':>14} {'f':>11} {'iter':>5} {'start':>10}"
        f" {'point':>5}  status",
    ]
    for p in front.points:
        mark = " (dominated)" if p.dominated and p.success else ""
        point = f"P{number[id(p)]}" if id(p) in number else "-"
        lines.append(
            f"{p.beta:>6.3f} {table_number(p.duration, '.4f'):>9} "
            f"{table_number(p.work, '.4f'):>14} {table_number(p.objective, '.5f'):>11} "
            f"{p.iterations:>5} {p.start:>10} {point:>5}  "
            f"{p.status}{mark}"
        )
    for k, group in enumerate(groups):
        if len(group) > 1:
            betas = ", ".join(f"{p.beta:g}" for p in group)
            lines.append(
                f"P{k + 1}: one point for beta = {betas} (T = {group[0].duration:.4f} s, "
                f"W = {group[0].work:.4f} N^2 m^2 s): the front is flat there"
            )
    return lines


def pareto_summary(front: ParetoFront, rtol: float = DISTINCT_RTOL) -> JSONDict:
    """Return ``front.summary()`` with the distinct points added.

    Parameters
    ----------
    front : ParetoFront
        The sweep's result.
    rtol : float
        Relative tolerance on T and W of :func:`distinct_points`.

    Returns
    -------
    dict
        The front's summary plus ``n_distinct``, ``distinct_rtol`` and ``distinct_points``
        (each: ``betas``, ``duration_s``, ``work``).
    """
    groups = distinct_points(front.points, rtol)
    return {
        **front.summary(),
        "n_distinct": len(groups),
        "distinct_rtol": rtol,
        "distinct_points": [
            {
                "betas": [p.beta for p in g],
                "duration_s": g[0].duration,
                "work": g[0].work,
            }
            for g in groups
        ],
    }
