"""Figures of the study-1 sweeps: multistart histogram, Pareto front, bound scaling.

Each function takes the sweep's typed result
(:class:`~youbot_opt.trajopt.multistart.MultistartResult`,
:class:`~youbot_opt.trajopt.pareto.ParetoFront`,
:class:`~youbot_opt.trajopt.bound_scaling.BoundScalingResult`) and returns a new
:class:`matplotlib.figure.Figure` (no pyplot, any backend). They are the
study's plots (spec ``trajopt.md``): the distinct local optima of 50 random
starts, the weighted-sum front of time against work, and the optimal
trajectories under the four bound scalings.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from youbot_opt.exceptions import ParameterError
from youbot_opt.viz.plots.trajopt import QUANTITIES, bound_pairs, new_figure

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from youbot_opt.trajopt.bound_scaling import BoundScalingResult
    from youbot_opt.trajopt.multistart import MultistartResult
    from youbot_opt.trajopt.pareto import ParetoFront

__all__ = ["plot_pareto", "plot_bound_scaling", "plot_multistart"]

_W_UNIT = r"N$^2$ m$^2$ s"  # unit of the work W = int tau . tau dt
_W_LABEL = f"work $W$ [{_W_UNIT}]"


def _axis_fraction(values: np.ndarray, limits: tuple[float, float], log: bool) -> np.ndarray:
    """Position of ``values`` along an axis as a fraction of its (log) range."""
    lo, hi = limits
    if log:
        values, lo, hi = np.log10(values), np.log10(lo), np.log10(hi)
    return (values - lo) / (hi - lo if hi > lo else 1.0)


def plot_pareto(
    front: ParetoFront,
    *,
    log: bool = False,
    label_spacing: float = 0.07,
    title: str | None = None,
    figsize: tuple[float, float] = (8.0, 5.5),
) -> Figure:
    """Duration against work of a weighted-sum sweep, each point's beta labelled.

    Non-dominated converged points are filled circles coloured by ``beta``
    (colour bar) and joined in order of duration; dominated converged points
    are grey crosses; failed weights are left out and counted in the title.
    Points are labelled with their ``beta`` where the labels do not crowd
    (the two ends always).

    Parameters
    ----------
    front : ParetoFront
        The sweep (:func:`youbot_opt.trajopt.pareto.pareto_sweep`).
    log : bool
        Logarithmic axes (useful when the extreme weights stretch T or W).
    label_spacing : float
        Smallest distance, as a fraction of the axes, between two labelled
        points.
    title : str, optional
        Axes title; default: counts of points, non-dominated and failed.
    figsize : tuple of float
        Figure size in [inch].

    Returns
    -------
    matplotlib.figure.Figure
        The figure. The non-dominated points are the line labelled
        ``"non-dominated"``, the dominated ones ``"dominated"``.

    Raises
    ------
    ParameterError
        If no point converged.
    """
    ok = [p for p in front.points if p.success and np.isfinite(p.duration) and np.isfinite(p.work)]
    if not ok:
        raise ParameterError("no point of the Pareto sweep converged", name="front")
    best = sorted((p for p in ok if not p.dominated), key=lambda p: (p.duration, p.work))
    worse = [p for p in ok if p.dominated]
    fig, axes = new_figure(1, 1, figsize)
    ax: Axes = axes[0, 0]
    betas = [p.beta for p in ok]
    cmap, norm = colormaps["plasma"], Normalize(min(0.0, *betas), max(1.0, *betas))
    ax.plot(
        [p.duration for p in best], [p.work for p in best], "-", color="0.6", linewidth=1.0,
        zorder=1, label="non-dominated",
    )  # fmt: skip
    ax.scatter(
        [p.duration for p in best], [p.work for p in best], c=[p.beta for p in best],
        cmap=cmap, norm=norm, s=36, edgecolors="k", linewidths=0.5, zorder=3,
    )  # fmt: skip
    if worse:
        ax.plot(
            [p.duration for p in worse], [p.work for p in worse], "x", color="0.45",
            markersize=7, linestyle="none", zorder=2, label="dominated",
        )  # fmt: skip
    if log:
        ax.set_xscale("log")
        ax.set_yscale("log")
    ax.autoscale_view()
    fx = _axis_fraction(np.array([p.duration for p in ok]), ax.get_xlim(), log)
    fy = _axis_fraction(np.array([p.work for p in ok]), ax.get_ylim(), log)
    order = sorted(range(len(ok)), key=lambda i: ok[i].beta)
    order = [order[0], order[-1], *order[1:-1]]  # extremes first
    placed: list[tuple[float, float]] = []
    for i in order:
        if all(np.hypot(fx[i] - x, fy[i] - y) >= label_spacing for x, y in placed):
            placed.append((fx[i], fy[i]))
            ax.annotate(
                f"$\\beta$={ok[i].beta:g}", (ok[i].duration, ok[i].work),
                xytext=(5, 4), textcoords="offset points", fontsize="small",
            )  # fmt: skip
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label=r"time weight $\beta$")
    ax.set_xlabel("duration $T$ [s]")
    ax.set_ylabel(_W_LABEL)
    ax.grid(True, which="both", alpha=0.3)
    handles = [
        Line2D([], [], color="0.6", linewidth=1.0, marker="o", markerfacecolor=cmap(0.5),
               markeredgecolor="k", markeredgewidth=0.5, label="non-dominated"),
    ]  # fmt: skip
    if worse:
        handles.append(
            Line2D([], [], color="0.45", marker="x", linestyle="none", label="dominated")
        )
    ax.legend(handles=handles, loc="upper right", fontsize="small")
    failed = len(front.points) - len(ok)
    ax.set_title(
        title
        or (
            f"Weighted-sum front: {len(front.points)} weights, {len(best)} non-dominated, "
            f"{len(worse)} dominated, {failed} failed (bounds {front.bound_scale:.0%})"
        ),
        fontsize="medium",
    )
    return fig


def plot_bound_scaling(
    study: BoundScalingResult,
    *,
    joint_names: Sequence[str] | None = None,
    title: str | None = None,
    figsize: tuple[float, float] | None = None,
) -> Figure:
    """Overlay the best trajectory of each bound scale: angles, speeds, torques per joint.

    A grid of 3 rows (q [rad], v [rad/s], tau [N m]) by one column per joint;
    each panel overlays the best solution of every scale in that scale's
    colour, with that scale's bounds dashed in the same colour.

    Parameters
    ----------
    study : BoundScalingResult
        The study (:func:`youbot_opt.trajopt.bound_scaling.bound_scaling_study`).
    joint_names : sequence of str, optional
        Column titles; default: the robot's joint names.
    title : str, optional
        Figure title; default: beta and the scales.
    figsize : tuple of float, optional
        Figure size in [inch]; default grows with the number of joints.

    Returns
    -------
    matplotlib.figure.Figure
        The figure; axes ``[row * nv + joint]``. Curves are labelled
        ``"scale <s>"``, bounds ``"_bound scale <s> <lower|upper>"``.

    Raises
    ------
    ParameterError
        If no scale has a converged solution, or ``joint_names`` has the wrong size.
    """
    solved = [
        (row, row.best.result)
        for row in study.rows
        if row.best is not None
        and row.best.result is not None
        and row.best.result.trajectory is not None
    ]
    if not solved:
        raise ParameterError("no scale of the study has a converged solution", name="study")
    first = solved[0][1]
    nv = first.problem.nv
    names = list(joint_names) if joint_names is not None else list(first.problem.robot.joint_names)
    if len(names) != nv:
        raise ParameterError(
            f"joint_names must have {nv} entries, got {len(names)}", name="joint_names"
        )
    fig, axes = new_figure(len(QUANTITIES), nv, figsize or (3.4 * nv + 2.5, 7.5), sharex="col")
    cmap = colormaps["viridis"]
    scales = [row.bound_scale for row in study.rows]
    for k, (row, res) in enumerate(solved):
        colour = cmap(0.9 * k / max(len(solved) - 1, 1))
        traj, limits = res.trajectory, bound_pairs(res.bounds())
        assert traj is not None
        s = f"{row.bound_scale:g}"
        for r, (key, _, _) in enumerate(QUANTITIES):
            values = getattr(traj, key)
            lo, hi = limits[key]
            for j in range(nv):
                ax = axes[r, j]
                ax.plot(traj.t, values[:, j], color=colour, linewidth=1.4, label=f"scale {s}")
                for side, level in (("lower", lo[j]), ("upper", hi[j])):
                    ax.axhline(
                        float(level), color=colour, linestyle="--", linewidth=0.9, alpha=0.8,
                        zorder=1, label=f"_bound scale {s} {side}",
                    )  # fmt: skip
    for r, (_, quantity, label) in enumerate(QUANTITIES):
        axes[r, 0].set_ylabel(f"joint {quantity} {label}")
        for j in range(nv):
            axes[r, j].grid(True, alpha=0.3)
            if r == 0:
                axes[r, j].set_title(names[j], fontsize="medium")
            if r == len(QUANTITIES) - 1:
                axes[r, j].set_xlabel("time t [s]")
    handles = [
        next(
            line
            for line in axes[0, 0].get_lines()
            if line.get_label() == f"scale {row.bound_scale:g}"
        )
        for row, _ in solved
    ]
    labels = [
        f"{row.bound_scale:.0%} bounds: f = {res.objective:.4f},\nT = {res.duration:.3f} s, "
        f"W = {res.work:.4g} {_W_UNIT}"
        for row, res in solved
    ]
    missing = [row.bound_scale for row in study.rows if all(row is not r for r, _ in solved)]
    fig.legend(handles, labels, loc="outside right upper", fontsize="small")
    extra = f"; no solution at {', '.join(f'{m:.0%}' for m in missing)}" if missing else ""
    fig.suptitle(
        title
        or (
            f"Best solution at each bound scale ({', '.join(f'{s:.0%}' for s in scales)}), "
            f"$\\beta$ = {study.beta:g}; bounds dashed{extra}"
        ),
        fontsize="medium",
    )
    return fig


def _bin_edges(values: np.ndarray, bins: int | Sequence[float]) -> np.ndarray:
    """Histogram edges: ``bins`` equal bins over the padded range, or the given edges.

    When all values fit in one bin (e.g. every start found the same optimum),
    an odd number of bins is centred on them over +-5 % of their value, so
    they fall in the middle bin instead of straddling an edge.
    """
    if isinstance(bins, str) or isinstance(bins, bool):
        raise ParameterError(f"bins must be a count >= 1 or edges, got {bins!r}", name="bins")
    if np.ndim(bins) == 1:
        edges = np.asarray(bins, dtype=float)
        if edges.size < 2 or not np.all(np.diff(edges) > 0):
            raise ParameterError("bin edges must be >= 2 increasing numbers", name="bins")
        return edges
    n = int(bins)  # type: ignore[arg-type]
    if n < 1:
        raise ParameterError(f"bins must be a count >= 1 or edges, got {bins!r}", name="bins")
    lo, hi = float(values.min()), float(values.max())
    centre, span = 0.5 * (lo + hi), hi - lo
    half = 0.05 * max(1.0, abs(centre))  # half window when the values coincide
    if span * n < 2.0 * half:
        n |= 1
        return np.linspace(centre - half, centre + half, n + 1)
    pad = 0.05 * span
    return np.linspace(lo - pad, hi + pad, n + 1)


def plot_multistart(
    ms: MultistartResult,
    *,
    obj_tol: float = 1e-5,
    dist_tol: float = 1e-2,
    bins: int | Sequence[float] = 40,
    max_marked: int = 8,
    title: str | None = None,
    figsize: tuple[float, float] = (11.0, 4.5),
) -> Figure:
    """Histogram of the converged starts' final objectives, and the distinct optima counted.

    Left: the histogram of the final objectives, each marked optimum a dashed
    vertical line. Right: one bar per marked optimum (lowest objective first)
    with its number of starts, labelled with its objective to 6 digits, ``T``
    and ``W``: optima that differ in trajectory but hardly in objective (their
    lines coincide on the left) stay apart there.

    Parameters
    ----------
    ms : MultistartResult
        The multistart (:func:`youbot_opt.trajopt.multistart.run_multistart`).
    obj_tol, dist_tol : float
        Clustering tolerances of :meth:`MultistartResult.distinct_optima`
        (relative objective; trajectory distance in [rad]).
    bins : int or sequence of float
        Number of equal bins over the objectives' range, or the bin edges.
        (numpy's automatic rules are not offered: on starts clustered at a few
        optima they can ask for millions of bins.)
    max_marked : int
        Largest number of optima marked (those with the most starts); the
        title says how many more there are.
    title : str, optional
        Figure title; default: starts, converged, failures by status, optima.
    figsize : tuple of float
        Figure size in [inch].

    Returns
    -------
    matplotlib.figure.Figure
        The figure: ``axes[0]`` the histogram, whose vertical lines are
        labelled ``"optimum <i>"``; ``axes[1]`` the bars (heights = counts).

    Raises
    ------
    ParameterError
        If no start converged.
    """
    converged = ms.converged
    if not converged:
        raise ParameterError(
            f"no start of the multistart converged ({ms.n_starts} starts)", name="ms"
        )
    objectives = np.array([s.objective for s in converged], dtype=float)
    optima = ms.distinct_optima(obj_tol, dist_tol)
    fig = Figure(figsize=figsize, layout="constrained")
    ax, bars = fig.subplots(1, 2, width_ratios=(3, 2))
    edges = _bin_edges(objectives, bins)
    ax.hist(
        objectives, bins=edges.tolist(), color="0.75", edgecolor="0.35", label="converged starts"
    )
    marked = sorted(
        sorted(optima, key=lambda o: -o.count)[: max(int(max_marked), 0)],
        key=lambda o: o.objective,
    )
    cmap = colormaps["tab10"]
    colours = [cmap(i % 10) for i in range(len(marked))]
    for i, opt in enumerate(marked):
        ax.axvline(opt.objective, color=colours[i], linestyle="--", linewidth=1.5,
                   label=f"optimum {i + 1}")  # fmt: skip
    ax.set_xlabel(r"final objective $f = \beta T + (1-\beta) W$")
    ax.set_ylabel("number of starts")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(loc="upper right", fontsize="small")
    positions = np.arange(len(marked))
    bars.bar(positions, [o.count for o in marked], color=colours, edgecolor="0.35")
    bars.set_xticks(
        positions,
        [
            f"{i + 1}: f = {o.objective:.6g}\nT = {o.duration:.4g} s\nW = {o.work:.5g}"
            for i, o in enumerate(marked)
        ],
        fontsize="small",
    )
    pad = max(0.75, (3 - len(marked)) / 2 + 0.5)  # a lone bar keeps a bar's width
    bars.set_xlim(-pad, len(marked) - 1 + pad)
    bars.set_xlabel(f"distinct optimum (W in {_W_UNIT})")
    bars.set_ylabel("starts reaching it")
    bars.yaxis.set_major_locator(MaxNLocator(integer=True))
    bars.grid(True, axis="y", alpha=0.3)
    failures = Counter(s.status for s in ms.starts if not s.success)
    failed = ", ".join(f"{n} {status}" for status, n in sorted(failures.items()))
    more = f", {len(optima) - len(marked)} more not marked" if len(optima) > len(marked) else ""
    fig.suptitle(
        title
        or (
            f"{ms.n_starts} start{'' if ms.n_starts == 1 else 's'} at $\\beta$ = {ms.beta:g}: "
            f"{len(converged)} converged"
            f"{' (' + failed + ')' if failed else ''}; {len(optima)} distinct "
            f"{'optimum' if len(optima) == 1 else 'optima'}{more}"
        ),
        fontsize="medium",
    )
    return fig
