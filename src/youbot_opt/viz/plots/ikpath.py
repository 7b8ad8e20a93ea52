"""Figures of IK-path results (matplotlib, no pyplot state: safe under Agg).

Every function takes result objects and returns a ``matplotlib.figure.Figure``
(or draws on a given ``Axes``): the path with its targets, whatever the robot
(:func:`plot_path`: a planar chain's arm at every visited configuration in its
plane, any other robot's frame path in 3-D), the joint motion per leg
(:func:`plot_leg_motion`), the convergence history (:func:`plot_convergence`),
a planar chain's reachable workspace under the joint limits with the targets
and their verdicts (:func:`plot_workspace`) and the minima found by a
multistart (:func:`plot_minima`). :func:`save_figures` writes them as PNG files.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib as mpl
import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from youbot_opt.ikpath.multistart import MultistartResult
from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.reachability.planar import ReachVerdict, check_reachability
from youbot_opt.ikpath.result import IKPathResult

__all__ = [
    "plot_path",
    "plot_convergence",
    "plot_workspace",
    "plot_minima",
    "plot_leg_motion",
    "save_figures",
]

_GRID_POINTS = 120_000  # joint-grid size for the workspace image
_VERDICT_COLORS = {"reachable": "tab:green", "unreachable": "tab:red", "undecided": "tab:orange"}


def _new_axes(ax: Axes | None, size: tuple[float, float] = (6.0, 6.0)) -> tuple[Figure, Axes]:
    if ax is not None:
        return ax.figure, ax  # type: ignore[return-value]
    fig = Figure(figsize=size, layout="constrained")
    return fig, fig.add_subplot()


def _mark_targets(ax: Axes, targets: np.ndarray, colors: Sequence[str] | None = None) -> None:
    for j, (x, y) in enumerate(targets):
        c = "k" if colors is None else colors[j]
        ax.plot(x, y, marker="x", color=c, markersize=10, markeredgewidth=2, zorder=5)
        ax.annotate(f"p{j + 1}", (x, y), textcoords="offset points", xytext=(6, 6), color=c)


def plot_path(result: IKPathResult, ax: Axes | None = None, samples_per_leg: int = 20) -> Figure:
    """Draw the path through the targets, whatever the robot.

    A planar chain (:attr:`CyclicIKProblem.chain`) is drawn in its plane: the
    arm at every configuration, the tip's cycle, the targets. Any other robot:
    the frame's path in 3-D (straight joint-space legs), the targets with a
    pose's axes or an approach axis.

    Parameters
    ----------
    result : IKPathResult
        A solve result.
    ax : matplotlib.axes.Axes, optional
        Axes to draw on (a 3-D one for a robot that is not a planar chain; a
        new figure by default).
    samples_per_leg : int
        Samples of the frame's path per leg (3-D drawing).

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    if result.problem.chain is None:
        return _plot_path_3d(result, ax, samples_per_leg)
    fig, ax = _new_axes(ax)
    chain = result.problem.planar_chain
    data = chain.create_data()
    cmap = mpl.colormaps["viridis"]
    s = result.problem.n_targets
    for j, q in enumerate(result.configurations):
        pts = chain.joint_positions(q, data)
        color = cmap(j / max(1, s - 1))
        ax.plot(pts[:, 0], pts[:, 1], "-o", color=color, lw=2.5, ms=5, label=f"q{j + 1}")
    tips = result.tip_positions()
    closed = np.vstack([tips, tips[:1]])
    ax.plot(closed[:, 0], closed[:, 1], ":", color="0.5", lw=1)
    _mark_targets(ax, result.problem.target_points)
    ax.plot(*chain.base, "ks", ms=8)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(
        f"{result.method}: E = {result.objective:.6g} rad², max residual "
        f"{result.max_position_error():.1e} m ({result.status.value})"
    )
    return fig


def plot_convergence(result: IKPathResult) -> Figure:
    """Distance to the final iterate, E and constraint violation per outer iteration.

    Parameters
    ----------
    result : IKPathResult
        A result with a non-empty history.

    Returns
    -------
    matplotlib.figure.Figure
        Three stacked panels sharing the iteration axis.
    """
    fig = Figure(figsize=(6.5, 7.0), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    hist = result.history
    it = np.array([h.iteration for h in hist])
    final = result.configurations
    dist = np.array([np.linalg.norm(h.x - final) for h in hist])
    moved = dist > 0.0  # the final iterate (and any equal to it) is at distance 0: omitted
    axes[0].semilogy(it[moved], dist[moved], "o-")
    axes[0].set_ylabel("|x_k - x*| [rad]")
    if not moved.all():
        axes[0].text(
            0.99,
            0.95,
            f"{int(np.count_nonzero(~moved))} iterate(s) equal to x* (distance 0) not shown",
            transform=axes[0].transAxes,
            ha="right",
            va="top",
            fontsize=8,
        )
    axes[1].plot(it, [h.objective for h in hist], "o-")
    axes[1].axhline(result.objective, color="0.5", ls="--", lw=1)
    axes[1].set_ylabel("E [rad²]")
    for key, style, label in (
        ("violation", "o-", "max |c|"),
        ("stationarity", "s--", "stationarity"),
    ):
        values = np.array([getattr(h, key) for h in hist], dtype=float)
        shown = values > 0.0  # exact zeros have no place on a log axis: left out, not floored
        axes[2].semilogy(it[shown], values[shown], style, label=label)
    axes[2].set_ylabel("max |c| [m], stationarity")
    axes[2].set_xlabel("outer iteration" if result.method == "al" else "IPOPT iteration")
    axes[2].legend(fontsize=8)
    for a in axes:
        a.grid(True, alpha=0.3)
    axes[0].set_title(f"convergence ({result.method}, {len(hist)} iterations)")
    return fig


def _workspace_points(problem: CyclicIKProblem) -> np.ndarray:
    """Tips of a regular joint grid over the limits (display only; verdicts are exact)."""
    chain = problem.planar_chain
    n = chain.n
    per = max(2, int(round(_GRID_POINTS ** (1.0 / n))))
    axes = []
    for lo, hi in zip(chain.q_lower, chain.q_upper, strict=True):
        if not problem.use_limits or not (np.isfinite(lo) and np.isfinite(hi)):
            lo, hi = -np.pi, np.pi
        axes.append(np.linspace(lo, hi, per))
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, n)
    phi = np.cumsum(grid + chain.angle_offset, axis=1)
    return chain.base + np.column_stack([np.cos(phi) @ chain.lengths, np.sin(phi) @ chain.lengths])


def plot_workspace(
    problem: CyclicIKProblem,
    verdicts: Sequence[ReachVerdict] | None = None,
    ax: Axes | None = None,
) -> Figure:
    """Draw the reachable workspace under the joint limits, the targets and their verdicts.

    The shaded hexagons are the cells hit by the tips of a regular joint grid
    over the limits (about 120 000 configurations; for display only); the
    target markers carry the exact verdicts of :mod:`youbot_opt.ikpath.reachability.planar`
    (green: reachable, red: unreachable with a line to the nearest reachable point,
    orange: undecided; all three are in the legend). The dashed circles bound the
    workspace without limits.

    Parameters
    ----------
    problem : CyclicIKProblem
        The problem (chain, targets, limits on/off).
    verdicts : sequence of ReachVerdict, optional
        Verdicts to show (computed if omitted).
    ax : matplotlib.axes.Axes, optional
        Axes to draw on.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    fig, ax = _new_axes(ax, (8.6, 6.0))
    verdicts = check_reachability(problem) if verdicts is None else verdicts
    pts = _workspace_points(problem)
    ax.hexbin(  # one colour for every cell a grid tip falls in: the region, not a density
        pts[:, 0],
        pts[:, 1],
        C=np.ones(len(pts)),
        reduce_C_function=np.max,
        gridsize=90,
        cmap=ListedColormap(["#b9d3ee"]),
        linewidths=0.2,
        edgecolors="#b9d3ee",
    )
    r_min, r_max = problem.planar_chain.reach
    t = np.linspace(0, 2 * np.pi, 400)
    for r in (r_min, r_max):
        if r > 0:
            ax.plot(
                problem.planar_chain.base[0] + r * np.cos(t),
                problem.planar_chain.base[1] + r * np.sin(t),
                "--",
                color="0.4",
                lw=1,
            )
    colors = [_VERDICT_COLORS[v.status.value] for v in verdicts]
    _mark_targets(ax, problem.target_points, colors)
    for v in verdicts:
        if not v.reachable:
            ax.plot([v.target[0], v.nearest[0]], [v.target[1], v.nearest[1]], "-", color="tab:red")
            ax.plot(*v.nearest, "o", color="tab:red", mfc="none")
    ax.plot(*problem.planar_chain.base, "ks", ms=8)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    limits = "joint limits" if problem.bounded else "no joint limits"
    ax.set_title(f"workspace, {limits} (grid image); exact verdicts", fontsize=10)
    handles = [
        Patch(facecolor="#b9d3ee", label="tips of a joint grid (display only)"),
        Line2D([], [], ls="--", color="0.4", lw=1, label="reach without limits"),
        Line2D([], [], ls="", marker="s", ms=7, color="k", label="base (joint 1)"),
    ] + [
        Line2D([], [], ls="", marker="x", mew=2, ms=9, color=color, label=f"target: {verdict}")
        for verdict, color in _VERDICT_COLORS.items()
    ]
    if any(not v.reachable for v in verdicts):
        handles.append(
            Line2D([], [], color="tab:red", marker="o", mfc="none", label="nearest reachable point")
        )
    # outside the axes, so it never hides the workspace, a target or the base
    ax.legend(
        handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=8
    )
    return fig


def plot_minima(result: MultistartResult) -> Figure:
    """Bar chart of the distinct local minima (E) and how many starts found each.

    Parameters
    ----------
    result : MultistartResult
        A multistart run.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    fig, ax = _new_axes(None, (7.0, 4.0))
    minima = result.minima[:15]
    labels = [f"{m.objective:.4g}" for m in minima]
    ax.bar(range(len(minima)), [m.count for m in minima], color="tab:blue")
    ax.set_xticks(range(len(minima)), labels, rotation=45, ha="right")
    ax.set_xlabel("E of the local minimum [rad²]")
    ax.set_ylabel("starts")
    failed = result.n_starts - result.n_converged
    shown = f", lowest {len(minima)} shown" if len(minima) < len(result.minima) else ""
    ax.set_title(
        f"{result.method}: {result.n_starts} start{'' if result.n_starts == 1 else 's'} "
        f"(seed {result.seed}), {len(result.minima)} "
        f"minim{'um' if len(result.minima) == 1 else 'a'}{shown}, {failed} failed"
    )
    ax.grid(True, axis="y", alpha=0.3)
    return fig


def save_figures(
    result: IKPathResult | MultistartResult,
    out_dir: str | Path,
    *,
    verdicts: Sequence[ReachVerdict] | None = None,
    dpi: int = 110,
) -> list[Path]:
    """Write the arm path, convergence, workspace (and minima) figures as PNG files.

    Parameters
    ----------
    result : IKPathResult or MultistartResult
        What to draw (for a multistart, its best result plus the minima chart).
    out_dir : str or Path
        Directory (created if missing).
    verdicts : sequence of ReachVerdict, optional
        Reachability verdicts for the workspace figure.
    dpi : int
        Resolution.

    Returns
    -------
    list of Path
        The files written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    best = result.best if isinstance(result, MultistartResult) else result
    figures = {
        "ikpath_arm.png": plot_path(best),
        "ikpath_workspace.png": plot_workspace(best.problem, verdicts),
    }
    if best.history:
        figures["ikpath_convergence.png"] = plot_convergence(best)
    if isinstance(result, MultistartResult):
        figures["ikpath_minima.png"] = plot_minima(result)
    paths = []
    for name, fig in figures.items():
        path = out / name
        fig.savefig(path, dpi=dpi)
        paths.append(path)
    return paths


def plot_leg_motion(result: IKPathResult, baseline: np.ndarray | None = None) -> Figure:
    """Joint motion per leg of a path: ``|q_{j+1,i} - q_{j,i}|`` stacked by joint.

    Parameters
    ----------
    result : IKPathResult
        The path (leg ``j`` goes from target ``j`` to ``j + 1``; the last closes the cycle).
    baseline : ndarray, shape (s, n), optional
        Configurations of another path (e.g. the greedy DLS baseline) whose
        per-leg motion norm is drawn as a line for comparison.
    """
    legs = np.abs(result.leg_motion())
    s, n = legs.shape
    fig, ax = _new_axes(None, (7.0, 4.0))
    bottom = np.zeros(s)
    x = np.arange(s)
    names = result.problem.joint_names
    for i in range(n):
        ax.bar(x, legs[:, i], bottom=bottom, label=names[i])
        bottom += legs[:, i]
    if baseline is not None:
        base = np.abs(np.roll(baseline, -1, axis=0) - baseline).sum(axis=1)
        ax.plot(x, base, "k--o", label="baseline (sum |dq|)")
    ax.set_xticks(x, [f"{j + 1}->{(j + 1) % s + 1}" for j in range(s)])
    ax.set_xlabel("leg (target -> target)")
    ax.set_ylabel("joint motion |dq_i| [rad]")
    ax.set_title(f"joint motion per leg, E = {result.objective:.4g} rad$^2$ ({result.method})")
    ax.legend(fontsize="small", ncols=2)
    return fig


def _plot_path_3d(result: IKPathResult, ax: Axes | None, samples_per_leg: int) -> Figure:
    """Draw the frame's path (straight joint-space legs) through the targets, in 3-D [m]."""
    ax3d: Any  # a mpl_toolkits.mplot3d Axes3D
    if ax is None:
        fig = Figure(figsize=(6.0, 6.0), layout="constrained")
        ax3d = fig.add_subplot(projection="3d")
    else:
        fig, ax3d = ax.figure, ax  # type: ignore[assignment]
    path = result.frame_path(samples_per_leg)
    ax3d.plot(path[:, 0], path[:, 1], path[:, 2], color="tab:blue", label="frame path")
    for j, target in enumerate(result.problem.targets):
        p = target.position
        ax3d.scatter(*p, color="tab:red", s=30)
        ax3d.text(*p, f" T{j + 1}", color="tab:red")
        if target.rotation is not None:
            for k, c in enumerate(("r", "g", "b")):
                axis = target.rotation[:, k] * 0.05
                ax3d.plot(*np.column_stack([p, p + axis]), color=c)
        elif target.approach is not None:
            ax3d.plot(*np.column_stack([p, p + 0.08 * target.approach]), color="k")
    ax3d.set_xlabel("x [m]")
    ax3d.set_ylabel("y [m]")
    ax3d.set_zlabel("z [m]")
    ax3d.set_title(f"{result.problem.frame}: {result.status.value}")
    return fig
