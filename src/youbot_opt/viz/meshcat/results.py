"""Replay several trajectory results together: side by side or as ghosts, labelled.

The distinct local optima of a multistart, points of a Pareto front or the
solutions under several bound scales are easier to compare in one scene.
:func:`export_results_html` writes them into one standalone HTML page (see
:mod:`youbot_opt.viz.meshcat.replay`) with a legend naming each result next to
the colour of its end-effector path; :func:`replay_results` plays them in a
live meshcat viewer. Copies side by side are spaced within the plane of a
planar motion (the youBot's x-z plane), so the camera sees each face on.
"""

from __future__ import annotations

import html
import logging
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import meshcat
import numpy as np

from youbot_opt._typing import Array
from youbot_opt.collision.scene import Scene
from youbot_opt.exceptions import ParameterError
from youbot_opt.viz.meshcat import scene
from youbot_opt.viz.meshcat.replay import html_target, replay, standalone_page, write_page
from youbot_opt.viz.meshcat.scene import RobotLike
from youbot_opt.viz.meshcat.server import MeshcatServer

if TYPE_CHECKING:
    from youbot_opt.trajopt.result import TrajOptResult
    from youbot_opt.trajopt.trajectory import Trajectory

__all__ = ["result_tracks", "replay_results", "export_results_html"]

logger = logging.getLogger(__name__)

_LEGEND = (
    '\n<div id="youbot-opt-legend" style="position: absolute; left: 8px; top: 8px; '
    "padding: 4px 8px; background: rgba(255, 255, 255, 0.85); border-radius: 4px; "
    'font: 13px sans-serif;">@ENTRIES@</div>'
)


def _legend(title: str, runs: Sequence[scene.Run], labels: Sequence[str]) -> str:
    """Build the HTML block naming each run next to the colour of its end-effector path."""
    entries = [f"<div><b>{html.escape(title)}</b></div>"]
    for run, label in zip(runs, labels, strict=True):
        swatch = (
            f'<span style="display: inline-block; width: 12px; height: 12px; '
            f'background: #{run.color:06x}; opacity: {run.opacity:g};"></span>'
        )
        entries.append(f"<div>{swatch} {html.escape(label)}</div>")
    return _LEGEND.replace("@ENTRIES@", "".join(entries))


_LAYOUTS = ("side_by_side", "ghosts")


def result_tracks(
    results: Sequence[TrajOptResult | Trajectory],
    labels: Sequence[str] | None = None,
    robot: RobotLike | None = None,
) -> tuple[RobotLike, list[tuple[Array, Array, str]]]:
    """Turn trajectory results into labelled tracks ``(t, q, label)`` of one robot.

    Parameters
    ----------
    results : sequence of TrajOptResult or Trajectory
        The motions; a result's ``trajectory`` knots are its track.
    labels : sequence of str, optional
        One per result; default ``"<i>: f = <objective>"`` (``"run <i>"`` for
        a bare trajectory).
    robot : RobotLike, optional
        Default: the first result's ``problem.robot``.

    Returns
    -------
    tuple
        The robot, and the tracks: times in [s], configurations in [rad], label.

    Raises
    ------
    ParameterError
        If ``results`` is empty, a result has no trajectory, the labels do not
        match, no robot is known, or a result's robot has another ``nq``.
    """
    items = list(results)
    if not items or (labels is not None and len(labels) != len(items)):
        raise ParameterError(
            f"need at least one result and one label per result; got {len(items)} results, "
            f"{'no' if labels is None else len(labels)} labels",
            name="results" if not items else "labels",
        )
    tracks: list[tuple[Array, Array, str]] = []
    for i, item in enumerate(items):
        problem = getattr(item, "problem", None)
        traj = getattr(item, "trajectory", item)
        if traj is None or not (hasattr(traj, "t") and hasattr(traj, "q")):
            raise ParameterError(
                f"results[{i}] must be a TrajOptResult with a trajectory or a Trajectory, "
                f"got a {type(item).__name__}{'' if traj is not None else ' without one'}",
                name="results",
            )
        robot = problem.robot if robot is None and problem is not None else robot
        if robot is not None and problem is not None and problem.robot.model.nq != robot.model.nq:
            raise ParameterError(
                f"results[{i}] is for a robot with nq = {problem.robot.model.nq}; the scene's "
                f"robot {robot.name!r} has nq = {robot.model.nq}",
                name="results",
            )
        objective = getattr(item, "objective", None)  # a result has one, a Trajectory none
        default = f"{i}: f = {objective:.5g}" if problem is not None else f"run {i}"
        tracks.append((traj.t, traj.q, default if labels is None else str(labels[i])))
    if robot is None:
        raise ParameterError("robot is required when only Trajectories are given", name="robot")
    scene.check_robot(robot)
    return robot, tracks


def _arrange(
    robot: RobotLike, tracks: list[tuple[Array, Array, str]], layout: str, spacing: Array | None
) -> dict[str, Any]:
    """Keyword arguments of :func:`scene.layout_runs` for ``layout``."""
    if layout not in _LAYOUTS:
        raise ParameterError(f"layout must be one of {_LAYOUTS}, got {layout!r}", name="layout")
    rest = tracks[1:]
    if layout == "ghosts":
        return {"ghosts": [(t, q) for t, q, _ in rest], "extra": [], "spacing": spacing}
    if spacing is None and rest:
        spacing = scene.side_by_side_spacing(robot, [(t, q) for t, q, _ in tracks])
    return {"ghosts": [], "extra": rest, "spacing": spacing}


def _scene_of(
    results: Sequence[TrajOptResult | Trajectory], obstacles: Scene | None
) -> Scene | None:
    """``obstacles``, or else the scene of the first result's problem clearance, if any."""
    if obstacles is not None or not results:
        return obstacles
    clearance = getattr(getattr(results[0], "problem", None), "clearance", None)
    return getattr(clearance, "scene", None)


def replay_results(
    results: Sequence[TrajOptResult | Trajectory],
    *,
    labels: Sequence[str] | None = None,
    layout: str = "side_by_side",
    robot: RobotLike | None = None,
    viewer: meshcat.Visualizer | MeshcatServer | str | None = None,
    ee_path: bool = True,
    spacing: Array | None = None,
    realtime: bool = True,
    speed: float = 1.0,
    frame_path: str = "youbot_opt",
    obstacles: Scene | None = None,
) -> meshcat.Visualizer:
    """Play several trajectory results together in a live meshcat viewer.

    ``results``, ``labels`` and ``robot`` are as in :func:`result_tracks`
    (copies are named by their labels); ``layout`` as in
    :func:`export_results_html`; ``obstacles`` as in :func:`export_results_html`;
    the other parameters as in :func:`replay`.

    Returns
    -------
    meshcat.Visualizer
        The client used.
    """
    robot, tracks = result_tracks(results, labels, robot)
    t, q, label = tracks[0]
    placed = _arrange(robot, tracks, layout, spacing)
    return replay(
        robot, t, q, viewer=viewer, frame_path=frame_path, ee_path=ee_path, realtime=realtime,
        speed=speed, label=label, obstacles=_scene_of(results, obstacles), **placed,
    )  # fmt: skip


def export_results_html(
    results: Sequence[TrajOptResult | Trajectory],
    path: str | Path,
    *,
    labels: Sequence[str] | None = None,
    layout: str = "side_by_side",
    robot: RobotLike | None = None,
    fps: float = 30.0,
    ee_path: bool = True,
    spacing: Array | None = None,
    loop: bool = True,
    frame_path: str = "youbot_opt",
    obstacles: Scene | None = None,
) -> Path:
    """Write one standalone HTML file that plays several trajectory results together.

    Parameters
    ----------
    results : sequence of TrajOptResult or Trajectory
        The motions, e.g. the distinct optima of a multistart or points of a
        Pareto front; each keeps its time grid (a shorter one holds its end pose).
    path : str or Path
        The HTML file to write; its folder must exist.
    labels : sequence of str, optional
        One per result: the copies' scene names and the page's legend (top
        left, each label next to the colour of its end-effector path).
    layout : {"side_by_side", "ghosts"}
        Copies next to each other, in order (a planar motion is spaced within
        its plane, :func:`~youbot_opt.viz.meshcat.scene.side_by_side_spacing`),
        or the first opaque and the others translucent over it.
    robot : RobotLike, optional
        Default: the first result's robot.
    fps, ee_path, spacing, loop, frame_path
        As in :func:`export_html`.
    obstacles : Scene, optional
        Obstacles drawn with the copies; default: the scene of the first
        result's problem clearance (none for a Trajectory or a problem without).

    Returns
    -------
    Path
        The HTML file written (``path``).

    Raises
    ------
    ParameterError
        On bad results, labels, layout or ``fps``, or a missing folder.
    ModelError
        If a mesh breaks the mesh policy.
    """
    target = html_target(path)
    if not (np.isfinite(fps) and fps > 0):
        raise ParameterError(f"fps must be a positive rate in [1/s], got {fps!r}", name="fps")
    robot, tracks = result_tracks(results, labels, robot)
    t, q, label = tracks[0]
    placed = _arrange(robot, tracks, layout, spacing)
    runs = scene.layout_runs(robot, t, q, root=frame_path, label=label, **placed)
    runs = scene.attach_obstacles(robot, runs, _scene_of(results, obstacles))
    title = "side by side, in this order" if layout == "side_by_side" else "first, then ghosts"
    legend = _legend(title, runs, [lab for _, _, lab in tracks])
    page = standalone_page(
        robot, runs, fps=fps, ee_path=ee_path, targets=None, loop=loop, legend=legend
    )
    return write_page(target, page)
