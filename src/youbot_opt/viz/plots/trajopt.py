"""Figures of one trajectory solve: joint curves, IPOPT convergence, the arm in 2-D.

The study's plots (spec ``trajopt.md``): :func:`plot_trajectory`,
:func:`plot_convergence`, :func:`plot_arm_2d`, :func:`plot_refinement` (and
:func:`plot_refinements`, a study's overview),
each returning a new Figure built without pyplot. Lines carry labels tests can
find: the joint name, or ``"_bound <quantity> <joint|all> <lower|upper>"`` for
a dashed bound.

>>> plot_trajectory(result).savefig("trajectory.png")  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from matplotlib import colormaps
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.ticker import FormatStrFormatter, MaxNLocator

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.problem import JointBounds
from youbot_opt.trajopt.result import TrajOptResult
from youbot_opt.trajopt.trajectory import Trajectory

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from youbot_opt.robot.model import RobotModel
    from youbot_opt.trajopt.multistart import MultistartResult, StartOutcome
    from youbot_opt.trajopt.refine import Refined, Refinement, RefinementRound

__all__ = [
    "plot_trajectory",
    "plot_convergence",
    "plot_arm_2d",
    "plot_refinement",
    "plot_refinements",
    "plot_clearance",
    "plan_times",
    "QUANTITIES",
]

QUANTITIES: tuple[tuple[str, str, str], ...] = (
    ("q", "angle", "q [rad]"),
    ("v", "speed", "v [rad/s]"),
    ("tau", "torque", r"$\tau$ [N m]"),
)
"""Trajectory arrays plotted, with their short name and axis label (unit in brackets)."""

_W_UNIT = r"N$^2$ m$^2$ s"  # unit of the work W = int tau . tau dt


def joint_colour(j: int) -> tuple[float, float, float, float]:
    """Colour of joint ``j`` (0-based) in every figure (matplotlib's ``tab10`` cycle)."""
    return colormaps["tab10"](j % 10)


def new_figure(
    nrows: int,
    ncols: int,
    figsize: tuple[float, float],
    *,
    sharex: bool | Literal["none", "all", "row", "col"] = False,
) -> tuple[Figure, npt.NDArray[np.object_]]:
    """Make a constrained-layout figure and its ``(nrows, ncols)`` array of axes (no pyplot)."""
    fig = Figure(figsize=figsize, layout="constrained")
    axes = fig.subplots(nrows, ncols, sharex=sharex, squeeze=False)
    return fig, axes


def plan_times(trajectory: Trajectory, samples: int) -> Array:
    """Return evenly spaced times over a plan, its first and last knot included.

    Parameters
    ----------
    trajectory : Trajectory
        The plan.
    samples : int
        How many times; fewer than 2 gives 2 (the ends).

    Returns
    -------
    ndarray, shape (max(samples, 2),)
        Times in [s] from ``trajectory.t[0]`` to ``trajectory.t[-1]``.
    """
    return np.linspace(float(trajectory.t[0]), float(trajectory.t[-1]), max(int(samples), 2))


def bound_pairs(bounds: JointBounds) -> dict[str, tuple[Array, Array]]:
    """Lower and upper bounds by trajectory array name (``"q"``, ``"v"``, ``"tau"``)."""
    return {
        "q": (bounds.q_lower, bounds.q_upper),
        "v": (bounds.v_lower, bounds.v_upper),
        "tau": (bounds.tau_lower, bounds.tau_upper),
    }


def _resolve_trajectory(
    result_or_trajectory: TrajOptResult | Trajectory,
) -> tuple[Trajectory, TrajOptResult | None]:
    if isinstance(result_or_trajectory, TrajOptResult):
        traj = result_or_trajectory.trajectory
        if traj is None:
            raise ParameterError(
                "the result has no trajectory to plot (status "
                f"{result_or_trajectory.status.value}: {result_or_trajectory.message})",
                name="result_or_trajectory",
            )
        return traj, result_or_trajectory
    if isinstance(result_or_trajectory, Trajectory):
        return result_or_trajectory, None
    raise ParameterError(
        f"expected a TrajOptResult or a Trajectory, got {type(result_or_trajectory).__name__}",
        name="result_or_trajectory",
    )


def _joint_names(names: Sequence[str] | None, nv: int, result: TrajOptResult | None) -> list[str]:
    if names is None:
        if result is not None:
            names = tuple(result.problem.robot.joint_names)
        else:
            names = tuple(f"joint {j + 1}" for j in range(nv))
    names = [str(n) for n in names]
    if len(names) != nv:
        raise ParameterError(
            f"joint_names must have {nv} entries, got {len(names)}", name="joint_names"
        )
    return names


def _draw_bounds(ax: Axes, key: str, bounds: tuple[Array, Array], names: Sequence[str]) -> None:
    """Dashed bound lines of one quantity: once in grey if all joints share it, else per joint."""
    for side, levels in zip(("lower", "upper"), bounds, strict=True):
        levels = np.asarray(levels, dtype=float).ravel()
        shared = levels.size > 1 and bool(np.all(np.isfinite(levels)))
        if shared and np.ptp(levels) <= 1e-12 * max(1.0, float(np.max(np.abs(levels)))):
            ax.axhline(float(levels[0]), color="0.3", linestyle="--", linewidth=1.0, alpha=0.8,
                       zorder=1, label=f"_bound {key} all {side}")  # fmt: skip
            continue
        for j, level in enumerate(levels):
            if np.isfinite(level):
                label = f"_bound {key} {names[j]} {side}"
                ax.axhline(float(level), color=joint_colour(j), linestyle="--", linewidth=1.0,
                           alpha=0.8, zorder=1, label=label)  # fmt: skip


def result_title(result: TrajOptResult) -> str:
    """One-line description of a solve: robot, beta, bound scale, T, W, f and status."""
    return (
        f"{result.problem.robot.name}: $\\beta$ = {result.beta:g}, bounds "
        f"{result.bound_scale:.0%}, T = {result.duration:.3f} s, W = {result.work:.4g} {_W_UNIT}, "
        f"f = {result.objective:.4f} ({result.status.value})"
    )


_PRISMATIC_QUANTITIES: tuple[tuple[str, str, str], ...] = (
    ("q", "position", "q [m]"),
    ("v", "speed", "v [m/s]"),
    ("tau", "force", r"$f$ [N]"),
)


def _unit_labels(
    prismatic: Sequence[bool], names: Sequence[str]
) -> tuple[tuple[str, str, str], ...]:
    """Axis labels with each joint kind's unit (empty: every joint revolute, :data:`QUANTITIES`).

    All prismatic: m, m/s, N. Mixed: rad, rad/s, N m, and the prismatic joints
    named with theirs (one axis per quantity, one unit per joint kind).
    """
    if not any(prismatic):
        return ()
    if all(prismatic):
        return _PRISMATIC_QUANTITIES
    which = ", ".join(n for n, p in zip(names, prismatic, strict=True) if p)
    return tuple(
        (key, kind, f"{label[: label.index('[')]}[{unit}]\n({which} in [{p_unit}])")
        for (key, kind, label), unit, p_unit in zip(
            (("q", "position", "q ["), ("v", "speed", "v ["), ("tau", "effort", r"$\tau$ [")),
            ("rad", "rad/s", "N m"),
            ("m", "m/s", "N"),
            strict=True,
        )
    )


def plot_trajectory(
    result_or_trajectory: TrajOptResult | Trajectory,
    bounds: JointBounds | None = None,
    *,
    show_bounds: bool = True,
    joint_names: Sequence[str] | None = None,
    title: str | None = None,
    figsize: tuple[float, float] = (9.0, 7.5),
) -> Figure:
    """Joint angles, speeds and torques against time, with the bounds dashed.

    Three stacked axes sharing the time axis [s]; one line per joint through
    the knot values (small markers at the knots), and each joint's lower and
    upper bound as a dashed line of the same colour.

    Parameters
    ----------
    result_or_trajectory : TrajOptResult or Trajectory
        A solve (its trajectory, scaled bounds and joint names are used) or a
        bare trajectory.
    bounds : JointBounds, optional
        Bounds to draw; default: the result's scaled bounds (none for a bare
        trajectory).
    show_bounds : bool
        Draw the bounds (dashed).
    joint_names : sequence of str, optional
        Legend entries; default: the robot's joint names (``"joint 1"``, ...
        for a bare trajectory).
    title : str, optional
        Title over the top axes; default: robot, beta, bound scale, T, W, f
        and status.
    figsize : tuple of float
        Figure size in [inch].

    Returns
    -------
    matplotlib.figure.Figure
        The figure; ``fig.axes[0..2]`` hold q [rad], v [rad/s] and tau [N m]
        (prismatic joints in [m], [m/s] and [N], named on the axis label).

    Raises
    ------
    ParameterError
        If the result has no trajectory, or ``joint_names`` or ``bounds`` do
        not match its joints.
    """
    traj, result = _resolve_trajectory(result_or_trajectory)
    nv = traj.v.shape[1]
    names = _joint_names(joint_names, nv, result)
    own_bounds = bounds is None and result is not None  # the result's scaled bounds
    if bounds is None and result is not None:
        bounds = result.bounds()
    limits = bound_pairs(bounds) if (bounds is not None and show_bounds) else {}
    for key, (lo, hi) in limits.items():
        if np.size(lo) != nv or np.size(hi) != nv:
            raise ParameterError(
                f"bounds of {key} have {np.size(lo)} entries, the trajectory has {nv} joints",
                name="bounds",
            )
    fig, axes = new_figure(len(QUANTITIES), 1, figsize, sharex=True)
    units = result.problem.robot.joint_units() if result is not None else ()
    labels_by_kind = _unit_labels([u.prismatic for u in units], names)
    for ax, (key, quantity, label) in zip(axes[:, 0], labels_by_kind or QUANTITIES, strict=True):
        values = getattr(traj, key)
        for j in range(nv):
            ax.plot(traj.t, values[:, j], color=joint_colour(j), marker=".", markersize=3,
                    label=names[j])  # fmt: skip
        if key in limits:
            _draw_bounds(ax, key, limits[key], names)
        ax.set_ylabel(f"joint {quantity} {label}")
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("time t [s]")
    axes[-1, 0].set_xlim(float(traj.t[0]), float(traj.t[-1]))
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if limits:
        scale = f" ({result.bound_scale:.0%})" if result is not None and own_bounds else ""
        handles.append(Line2D([], [], color="0.3", linestyle="--", linewidth=1.0))
        labels.append(f"bounds{scale}")
    fig.legend(handles, labels, loc="outside right upper")
    if title is None and result is not None:
        title = result_title(result)
    if title:  # over the top axes, clear of the legend at the right
        axes[0, 0].set_title(title, fontsize="medium")
    return fig


def _refinement_items(record: Refinement) -> list[tuple[str, Array, bool]]:
    """(label, objective history, success) of each round's solve of a refinement."""
    items = []
    for r in record.rounds:
        history = np.asarray(r.objective_history, dtype=float)
        if history.size:
            ok = r.status in ("solved", "solved_acceptable")
            status = "" if ok else f", {r.status}"
            label = f"round {r.index} ({r.n_knots} knots): f = {r.objective:.4f}{status}"
            items.append((label, history, ok))
    return items


def _convergence_items(results: Any) -> tuple[list[tuple[str, Array, bool]], str]:
    """(label, objective history, success) of each run, and what the runs are.

    The runs are a refinement's rounds, a multistart's starts or plain results.
    """
    from youbot_opt.trajopt.multistart import MultistartResult, StartOutcome
    from youbot_opt.trajopt.refine import Refined, Refinement

    if isinstance(results, Refined):
        results = results.refinement
    if isinstance(results, Refinement):
        return _refinement_items(results), "rounds"
    kind = "starts" if isinstance(results, MultistartResult) else "runs"
    if isinstance(results, MultistartResult):
        results = results.starts
    if isinstance(results, TrajOptResult):
        results = [results]
    items: list[tuple[str, Array, bool]] = []
    for i, item in enumerate(results):
        if isinstance(item, StartOutcome):
            kind = "starts"
            if item.result is None:
                continue  # the start raised: no history
            label = "straight line" if item.index < 0 else f"start {item.index}"
            res = item.result
        elif isinstance(item, TrajOptResult):
            res = item
            label = f"seed {res.seed}" if res.seed is not None else f"run {i}"
        else:
            raise ParameterError(
                "results must be TrajOptResults, StartOutcomes, a MultistartResult or a "
                f"refinement, got {type(item).__name__}",
                name="results",
            )
        history = np.asarray(res.objective_history, dtype=float)
        if history.size:
            status = "" if res.success else f", {res.status.value}"
            items.append((f"{label}: f = {res.objective:.4f}{status}", history, res.success))
    return items, kind


def _convergence_title(kind: str, items: list[tuple[str, Array, bool]]) -> str:
    """Say what the figure shows: the solve, the starts or the refinement rounds."""
    n, n_ok = len(items), sum(ok for _, _, ok in items)
    if kind == "rounds":
        what = (
            "the solve of the refinement's round"
            if n == 1
            else f"the solves of {n} refinement rounds"
        )
        return f"Convergence of {what} ({n_ok} converged)"
    if kind == "runs" and n == 1:
        return f"Convergence of the solve ({'converged' if n_ok else 'not converged'})"
    noun = kind if n != 1 else kind[:-1]
    return f"Convergence of {n} {noun} ({n_ok} converged)"


def plot_convergence(
    results: MultistartResult
    | Refined
    | Refinement
    | Sequence[StartOutcome]
    | Sequence[TrajOptResult],
    *,
    log: bool = True,
    max_legend: int = 12,
    title: str | None = None,
    figsize: tuple[float, float] = (9.0, 4.5),
) -> Figure:
    """Objective against IPOPT iteration for several starts, or each round of a refinement.

    One line per start (or per refinement round's solve): IPOPT's objective at
    iterations ``0 .. iterations`` (``TrajOptResult.objective_history``;
    iteration 0 is the initial guess, a refinement round's warm start).
    Converged starts are solid and end in a dot, failed ones dotted and end in
    a cross. Up to ``max_legend`` runs are named in the legend with their
    final objective; beyond that, a colour bar gives the run's (start's,
    round's) number and the legend only the line styles.

    Parameters
    ----------
    results : MultistartResult, Refined, Refinement, sequence of StartOutcome or of TrajOptResult
        The runs (starts that raised, having no history, are skipped); for a
        refinement (what :func:`~youbot_opt.trajopt.refine.refine` returns, or
        its record), the solve of every round.
    log : bool
        Logarithmic objective axis (symmetric-log if an objective is <= 0).
    max_legend : int
        Largest number of runs listed one by one in the legend.
    title : str, optional
        Axes title; default: what the runs are (the solve, the starts, the
        refinement rounds), how many and how many converged.
    figsize : tuple of float
        Figure size in [inch].

    Returns
    -------
    matplotlib.figure.Figure
        The figure (one axes).

    Raises
    ------
    ParameterError
        If no run has an objective history.
    """
    items, kind = _convergence_items(results)
    if not items:
        raise ParameterError("no result with an objective history to plot", name="results")
    fig, axes = new_figure(1, 1, figsize)
    ax: Axes = axes[0, 0]
    cmap = colormaps["viridis"]
    for k, (label, history, ok) in enumerate(items):
        ax.plot(
            np.arange(history.size), history, color=cmap(k / max(len(items) - 1, 1)),
            linestyle="-" if ok else ":", marker="o" if ok else "x", markevery=[-1],
            markersize=4, linewidth=1.2, label=label,
        )  # fmt: skip
    if log:
        finite = np.concatenate([h[np.isfinite(h)] for _, h, _ in items])
        ax.set_yscale("log" if finite.size and np.all(finite > 0) else "symlog")
        ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.yaxis.set_minor_formatter(FormatStrFormatter("%g"))
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("IPOPT iteration")
    ax.set_ylabel(r"objective $f = \beta T + (1-\beta) W$")
    ax.grid(True, which="both", alpha=0.3)
    n_ok = sum(ok for _, _, ok in items)
    ax.set_title(title or _convergence_title(kind, items))
    if len(items) <= max_legend:
        fig.legend(loc="outside right upper", fontsize="small")
        return fig
    done = Line2D([], [], color="0.3", marker="o", label=f"converged ({n_ok})")
    styles = [done] if n_ok else []
    if n_ok < len(items):
        failed = f"failed ({len(items) - n_ok})"
        styles.append(Line2D([], [], color="0.3", linestyle=":", marker="x", label=failed))
    ax.legend(handles=styles, loc="upper right", fontsize="small")
    norm = Normalize(0, max(len(items) - 1, 1))
    number = {"starts": "start number", "rounds": "round"}.get(kind, "run number")
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label=number)
    bar.locator = MaxNLocator(integer=True)
    bar.update_ticks()
    return fig


# ------------------------------------------------------------------- 2-D arm
def _plane_axes(plane: str) -> tuple[int, int]:
    names = {"x": 0, "y": 1, "z": 2}
    if len(plane) != 2 or plane[0] not in names or plane[1] not in names or plane[0] == plane[1]:
        raise ParameterError(
            f"plane must be two distinct axes among x, y, z (e.g. 'xz'), got {plane!r}",
            name="plane",
            value=plane,
        )
    return names[plane[0]], names[plane[1]]


def chain_points(robot: RobotModel, q: Array, data: pin.Data | None = None) -> Array:
    """Root-frame positions in [m] of the joints from the root to the tip frame, then the tip.

    Joints are those on the kinematic path to ``robot.tip_frame`` (``oMi``
    after ``pin.framesForwardKinematics``), ordered from the root; the last row
    is the tip frame's origin (``oMf``). Shape (k + 1, 3).
    """
    model = robot.model
    fid = robot.frame_id(robot.tip_frame)
    data = robot.create_data() if data is None else data
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    path: list[int] = []
    joint = int(model.frames[fid].parentJoint)
    while joint > 0:
        path.append(joint)
        joint = int(model.parents[joint])
    pts = [np.array(data.oMi[j].translation) for j in reversed(path)]
    pts.append(np.array(data.oMf[fid].translation))
    return np.array(pts)


def _root_name(robot: RobotModel) -> str:
    """Name of the root body (the youBot's ``"platform"``), for axis labels."""
    for frame in robot.model.frames:
        if int(frame.parentJoint) == 0 and frame.type == pin.FrameType.BODY:
            return str(frame.name)
    return "root"


def _root_shapes(robot: RobotModel, rows: tuple[int, int]) -> list[tuple[Array, Array, Any]]:
    """Project the root-attached boxes and cylinders: (lower corner, size, colour) rectangles."""
    shapes = []
    for go in robot.visual_model.geometryObjects:
        if int(go.parentJoint) != 0:
            continue
        geom = go.geometry
        if hasattr(geom, "halfSide"):
            half = np.asarray(geom.halfSide, dtype=float)
        elif hasattr(geom, "radius") and hasattr(geom, "halfLength"):
            half = np.array([geom.radius, geom.radius, geom.halfLength], dtype=float)
        else:
            continue
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        corners = (go.placement.rotation @ (signs * half).T).T + go.placement.translation
        flat = corners[:, list(rows)]
        lo, hi = flat.min(axis=0), flat.max(axis=0)
        shapes.append((lo, hi - lo, tuple(np.asarray(go.meshColor, dtype=float))))
    return shapes


def plot_arm_2d(
    robot: RobotModel | None,
    trajectory: Trajectory | TrajOptResult,
    *,
    n_frames: int = 8,
    times: Sequence[float] | Array | None = None,
    plane: str = "xz",
    show_platform: bool = True,
    tip_path: bool = True,
    tip_samples: int = 200,
    title: str | None = None,
    figsize: tuple[float, float] = (7.5, 6.0),
) -> Figure:
    """Draw the arm on its platform at several times (a stroboscopic picture of the motion).

    Each pose is drawn as a line through the joints on the path to the tip
    frame and the tip (Pinocchio frame placements, projected on ``plane``),
    coloured by time; the tip path is dashed, the platform's box and cylinder
    geometry (visual objects fixed to the root) drawn as rectangles.

    Parameters
    ----------
    robot : RobotModel or None
        The robot; ``None`` takes ``trajectory.problem.robot`` of a result.
    trajectory : Trajectory or TrajOptResult
        The motion (a result's ``trajectory``).
    n_frames : int
        Number of poses drawn, evenly spaced in time from start to end (>= 2).
    times : sequence of float, optional
        Times in [s] of the poses, instead of ``n_frames``.
    plane : str
        Root-frame axes of the drawing plane, horizontal then vertical
        (``"xz"``: the youBot's platform x-z plane).
    show_platform : bool
        Draw the root-attached box and cylinder geometry.
    tip_path : bool
        Draw the tip's path over the whole motion (dashed).
    tip_samples : int
        Samples of the dashed tip path (>= 2).
    title : str, optional
        Axes title; default: robot name, number of poses and duration.
    figsize : tuple of float
        Figure size in [inch].

    Returns
    -------
    matplotlib.figure.Figure
        The figure. Pose lines are labelled ``"t = <time> s"`` with
        ``gid = "pose <k>"``; the tip path is labelled ``"tip path"``.

    Raises
    ------
    ParameterError
        On a bad ``plane``, ``n_frames``, ``times`` or a missing robot.
    """
    traj, result = _resolve_trajectory(trajectory)
    if robot is None:
        if result is None:
            raise ParameterError("robot is required for a bare Trajectory", name="robot")
        robot = result.problem.robot
    rows = _plane_axes(plane)
    if times is None:
        if isinstance(n_frames, bool) or not isinstance(n_frames, int) or n_frames < 2:
            raise ParameterError(f"n_frames must be an int >= 2, got {n_frames!r}", name="n_frames")
        poses_t = np.linspace(float(traj.t[0]), float(traj.t[-1]), n_frames)
    else:
        poses_t = np.asarray(times, dtype=float).ravel()
        if poses_t.size == 0 or not np.all(np.isfinite(poses_t)):
            raise ParameterError("times must be a non-empty list of finite times [s]", name="times")
    if tip_samples < 2:
        raise ParameterError(f"tip_samples must be >= 2, got {tip_samples!r}", name="tip_samples")

    fig, axes = new_figure(1, 1, figsize)
    ax: Axes = axes[0, 0]
    if show_platform:
        for corner, size, colour in _root_shapes(robot, rows):
            ax.add_patch(Rectangle(tuple(corner), size[0], size[1], color=colour, alpha=0.5))
    cmap, norm = colormaps["viridis"], Normalize(float(traj.t[0]), float(traj.t[-1]))
    for k, time in enumerate(poses_t):
        pts = chain_points(robot, traj(float(time)))[:, list(rows)]
        ax.plot(
            pts[:, 0], pts[:, 1], "-o", color=cmap(norm(time)), markersize=4, linewidth=2.5,
            alpha=0.9, label=f"t = {time:.2f} s", gid=f"pose {k}",
        )  # fmt: skip
    if tip_path:
        dense = np.linspace(float(traj.t[0]), float(traj.t[-1]), int(tip_samples))
        data = robot.create_data()
        tips = np.array([chain_points(robot, q, data)[-1] for q in traj(dense)])[:, list(rows)]
        ax.plot(tips[:, 0], tips[:, 1], "--", color="0.35", linewidth=1.0, label="tip path")
    ax.set_aspect("equal", adjustable="box")
    root = _root_name(robot)
    ax.set_xlabel(f"{root} {'xyz'[rows[0]]} [m]")
    ax.set_ylabel(f"{root} {'xyz'[rows[1]]} [m]")
    ax.grid(True, alpha=0.3)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label="time t [s]")
    if tip_path:
        ax.legend(handles=[ax.get_lines()[-1]], loc="best", fontsize="small")
    ax.set_title(
        title or f"{robot.name}: {poses_t.size} poses over {traj.duration:.3g} s",
        fontsize="medium",
    )
    return fig


_SPLIT_COLOUR = "tab:red"  # the intervals a refinement round splits


def _round_verdict(r: RefinementRound, tolerance: float, *, certify: bool = True) -> str:
    """Return the verdict of one refinement round on its own, as :func:`refine` judges the last.

    ``"certified"`` when the solve succeeded, every interval is within
    ``tolerance`` and (with ``certify``) the certificate passed; otherwise what
    failed: ``"solve <status>"``, ``"error 1.7e-03 > 0.001, cert. passes"``,
    ``"cert. fails"`` or ``"no cert."``.
    """
    if r.status not in ("solved", "solved_acceptable"):
        return f"solve {r.status}"
    cert = {True: "cert. passes", False: "cert. fails", None: "no cert."}[r.certificate_passed]
    if not r.max_error <= tolerance:  # NaN: no estimate
        return f"error {r.max_error:.2g} > {tolerance:g}, {cert}"
    if r.certificate_passed or not certify:
        return "certified"
    return cert


def plot_refinement(refined: Refined | Refinement, *, title: str | None = None) -> Figure:
    """Where the knots went in each refinement round, and why.

    Top: the knots of every round (one row per round, a tick per knot, the
    intervals whose error exceeds the tolerance, split in the next round, in
    red, named in a legend). Bottom: each interval's relative collocation error
    against time, one step curve per round, with the tolerance dashed. Rounds
    are labelled with their knots, ``f`` and their own verdict
    ("certified" only for a round that is, on its own).

    Parameters
    ----------
    refined : Refined or Refinement
        What :func:`youbot_opt.trajopt.refine.refine` returns, or its record.
    title : str, optional
        Figure title (default: the refinement's outcome).

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ParameterError
        If ``refined`` is not a refinement (a bare result: refine it first) or
        no round has an error estimate.
    """
    from youbot_opt.trajopt.refine import Refined, Refinement  # imports the solver

    record = refined.refinement if isinstance(refined, Refined) else refined
    if not isinstance(record, Refinement):
        raise ParameterError(
            f"cannot plot the refinement of a {type(refined).__name__}: pass what refine() "
            "returns (a bare result was not refined)",
            name="refined",
        )
    rounds = [r for r in record.rounds if r.t.size > 1]
    if not rounds:
        raise ParameterError("no refinement round has an error estimate", name="refined")
    fig, axes = new_figure(2, 1, figsize=(8.0, 6.0), sharex=True)
    ax_grid, ax_err = axes[0, 0], axes[1, 0]
    cmap = colormaps["viridis"]
    tol = record.budget.tolerance
    n_split = 0
    for i, r in enumerate(rounds):
        colour = cmap(i / max(1, len(rounds) - 1))
        split = r.errors > tol
        n_split += int(np.count_nonzero(split))
        ax_grid.vlines(r.t, i - 0.35, i + 0.35, colors=[colour], linewidth=0.8)
        starts, ends = r.t[:-1][split], r.t[1:][split]
        ax_grid.hlines(np.full(starts.size, i), starts, ends, colors=_SPLIT_COLOUR, linewidth=2.5)
        label = (
            f"round {r.index}: {r.n_knots} knots, f = {r.objective:.5g}, "
            f"{_round_verdict(r, tol, certify=record.budget.certify)}"
        )
        ax_err.stairs(np.maximum(r.errors, 1e-16), r.t, color=colour, label=label)
    ax_grid.set_yticks(range(len(rounds)), [f"{r.index} ({r.n_knots})" for r in rounds])
    ax_grid.set_ylabel("round (knots)")
    ax_grid.invert_yaxis()
    if n_split:
        split_line = Line2D([], [], color=_SPLIT_COLOUR, linewidth=2.5)
        ax_grid.legend([split_line], [f"interval error > {tol:g}: split in the next round"],
                       loc="upper center", bbox_to_anchor=(0.5, 0.0), fontsize="small",
                       framealpha=0.9)  # fmt: skip
    ax_err.axhline(tol, color="k", linestyle="--", linewidth=1.0, label=f"tolerance {tol:g}")
    ax_err.set_yscale("log")
    ax_err.set_xlabel("t [s]")
    ax_err.set_ylabel("relative interval error")
    ax_err.legend(fontsize="small", loc="best")
    status = "certified" if record.certified else "not certified"
    ax_grid.set_title(title or f"mesh refinement: {status}, {len(record.rounds)} round(s)")
    return fig


def plot_refinements(
    records: Sequence[Refinement], labels: Sequence[str], *, title: str | None = None
) -> Figure:
    """Overview of a study's refinements: one column per plan, in order.

    Top: each plan's knots in its first round (open circle) and its final
    round (a filled dot if certified, a red cross if not), joined by a line;
    the legend names the plans that were not certified. Bottom: the number of
    rounds of each plan (a bar, hatched red if not certified). The title gives
    the budget and how many plans were certified. :func:`plot_refinement`
    draws one plan's rounds in detail.

    Parameters
    ----------
    records : sequence of Refinement
        The refinement records (:attr:`Refined.refinement`), one per plan.
    labels : sequence of str
        Each plan's label (e.g. ``"beta = 0.3"``), the x axis' ticks.
    title : str, optional
        Figure title (default: the number of plans, the budget and how many were certified).

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ParameterError
        If there is no record, or not one label per record.
    """
    if not records:
        raise ParameterError("no refinement to draw", name="records")
    if len(labels) != len(records):
        raise ParameterError(f"{len(labels)} labels for {len(records)} refinements", name="labels")
    x = np.arange(len(records))
    first = np.array([r.rounds[0].n_knots if r.rounds else np.nan for r in records], float)
    final = np.array([r.rounds[-1].n_knots if r.rounds else np.nan for r in records], float)
    n_rounds = np.array([len(r.rounds) for r in records])
    ok = np.array([r.certified for r in records], dtype=bool)
    width = min(16.0, max(8.0, 0.28 * len(records) + 2.0))
    fig, axes = new_figure(2, 1, figsize=(width, 6.0), sharex=True)
    ax_k, ax_r = axes[0, 0], axes[1, 0]
    ax_k.vlines(x, np.fmin(first, final), np.fmax(first, final), colors="0.6", linewidth=1.0)
    ax_k.plot(x, first, "o", mfc="none", mec="0.3", label="first round's knots")
    ax_k.plot(x[ok], final[ok], "o", color="tab:green", label="final knots: certified")
    if not ok.all():
        failed = [str(lab) for lab, good in zip(labels, ok, strict=True) if not good]
        named = ", ".join(failed[:4]) + (f" and {len(failed) - 4} more" if len(failed) > 4 else "")
        ax_k.plot(x[~ok], final[~ok], "X", color=_SPLIT_COLOUR, markersize=9,
                  label=f"final knots: NOT certified ({named})")  # fmt: skip
    ax_k.set_ylim(0.0, 1.6 * np.nanmax(np.fmax(first, final)))  # room for the legend above
    ax_k.set_ylabel("knots")
    ax_k.legend(fontsize="small", loc="upper center")
    ax_r.bar(x[ok], n_rounds[ok], color="tab:green", alpha=0.7, label="rounds: certified")
    if not ok.all():
        ax_r.bar(x[~ok], n_rounds[~ok], color="none", edgecolor=_SPLIT_COLOUR, hatch="//",
                 label="rounds: not certified")  # fmt: skip
    ax_r.set_ylim(0.0, 1.4 * n_rounds.max() + 0.5)  # room for the legend above the bars
    ax_r.set_ylabel("rounds")
    ax_r.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax_r.set_xticks(x, [str(lab) for lab in labels], rotation=90 if len(records) > 8 else 0,
                    fontsize="small")  # fmt: skip
    ax_r.legend(fontsize="small", loc="upper center", ncol=2)
    budgets = sorted({r.budget.describe() for r in records})
    ax_k.set_title(
        title
        or f"mesh refinement of {len(records)} plans: {int(ok.sum())}/{len(records)} certified\n"
        f"({'; '.join(budgets)})",
        fontsize="medium",
    )
    return fig


def plot_clearance(result: TrajOptResult, *, samples: int = 400) -> Figure:
    """Plot coal's clearance over time: the closest pair per group, and the margin.

    Groups: the robot against itself, and each obstacle of the problem's scene;
    each curve is the smallest exact distance of the group's pairs at each of
    ``samples`` times of the plan, the knots marked; its legend entry names the
    group's closest pair, its distance and when.

    Parameters
    ----------
    result : TrajOptResult
        A result with a trajectory and a problem with a clearance.
    samples : int
        Sample times over the plan (>= 2).

    Returns
    -------
    Figure
        One axes: distance [m] over time [s], the margin as a dashed line.

    Raises
    ------
    ParameterError
        The result has no trajectory, or its problem no clearance.
    """
    from youbot_opt.collision.clearance import clearance_checker

    spec = result.problem.clearance
    traj = result.trajectory
    if spec is None or traj is None:
        raise ParameterError(
            "plot_clearance needs a result with a trajectory and a clearance", name="result"
        )
    robot = result.problem.robot
    checker = clearance_checker(robot, spec)
    names = checker.model.pair_names
    obstacles = {o.name for o in spec.scene.obstacles}
    groups: dict[str, list[int]] = {}
    for i, (_, b) in enumerate(names):
        groups.setdefault(b if b in obstacles else "self-collision", []).append(i)
    t = plan_times(traj, samples)
    d = np.array([checker.distances(robot, traj(ti)) for ti in t]).reshape(t.size, len(names))
    dk = np.array([checker.distances(robot, q) for q in traj.q]).reshape(len(traj.t), len(names))
    fig, axes = new_figure(1, 1, (7.0, 3.6))
    ax = axes[0, 0]
    for g, (label, rows) in enumerate(sorted(groups.items())):
        colour = joint_colour(g)
        k, j = np.unravel_index(np.argmin(d[:, rows]), (t.size, len(rows)))
        a, b = names[rows[j]]
        closest = f"{label}: {a} - {b}, {d[k, rows[j]]:.3g} m at {t[k]:.3g} s"
        ax.plot(t, d[:, rows].min(axis=1), color=colour, label=closest)
        ax.plot(traj.t, dk[:, rows].min(axis=1), "o", color=colour, markersize=3)
    ax.axhline(spec.margin, color="k", linestyle="--", linewidth=1.0, label="margin")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("clearance [m]")
    ax.set_title(f"clearance (coal, closest pair per group; margin {spec.margin:g} m)")
    if groups:
        ax.legend(loc="best", fontsize="small")
    return fig
