"""Meshcat replay of IK-path results: live, or as one standalone HTML file.

Turns an :class:`~youbot_opt.ikpath.result.IKPathResult` into the robot, time
grid and configurations that :func:`~youbot_opt.viz.replay` and
:func:`~youbot_opt.viz.export_html` draw: the cyclic path, linear in joint
space between targets, with the targets and the tip path marked and other
minima as ghosts; spatial results replay on the robot's own visuals
(:func:`export_spatial_ikpath_html`). Conventions: docs/design.md, "Module notes".

>>> export_ikpath_html(result, "path.html", segment_time=1.0)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.result import IKPathResult

if TYPE_CHECKING:
    import meshcat

    from youbot_opt.viz.meshcat.scene import RobotLike
    from youbot_opt.viz.meshcat.server import MeshcatServer

__all__ = [
    "ReplayRobot",
    "replay_robot",
    "replay_track",
    "replay_targets",
    "replay_ikpath",
    "export_ikpath_html",
    "spatial_replay_robot",
    "spatial_replay_track",
    "replay_spatial_ikpath",
    "export_spatial_ikpath_html",
]

_TARGET_RGBA = np.array([0.84, 0.15, 0.16, 1.0])
_TARGET_RADIUS_IN_LINK_RADII = 1.3  # [-] target marker radius relative to the link radius


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class ReplayRobot:
    """What :mod:`youbot_opt.viz` needs to draw a chain (the ``RobotLike`` protocol).

    Attributes
    ----------
    name : str
        Scene name of the arm.
    model : pinocchio.Model
        The chain's kinematic model.
    visual_model : pinocchio.GeometryModel
        The chain's cylinders and spheres plus one fixed sphere per target.
    package_dirs : tuple
        Empty: every visual is a primitive shape.
    tip_frame : str
        The tip frame, whose path is drawn.
    """

    name: str
    model: pin.Model
    visual_model: pin.GeometryModel
    package_dirs: tuple[str, ...]
    tip_frame: str


def _check_segment_time(segment_time: float) -> float:
    value = float(segment_time)
    if not (np.isfinite(value) and value > 0.0):
        raise ParameterError(
            f"segment_time must be a positive duration in [s], got {segment_time!r}",
            name="segment_time",
            value=segment_time,
        )
    return value


def replay_targets(result: IKPathResult) -> Array:
    """Targets of ``result`` as points of the viewer, shape (s, 3) in [m] (z = 0)."""
    targets = result.problem.target_points
    return np.column_stack([targets, np.zeros(len(targets))])


def replay_robot(result: IKPathResult) -> ReplayRobot:
    """Return the chain of ``result`` with a visible marker at every target.

    The markers are spheres fixed to the world (joint 0) at the targets, with
    a radius of 1.3 link radii, so that they scale with the arm (the viewer's
    own target spheres have a fixed radius of 2 cm).

    Returns
    -------
    ReplayRobot
        Name, model, visual model (chain visuals + ``target_<j>`` spheres),
        no package directories, tip frame.
    """
    chain = result.problem.planar_chain
    visual = chain.visual_model.copy()
    link_radius = 0.04 * float(np.mean(chain.lengths))  # [m] as in PlanarChain's visuals
    radius = _TARGET_RADIUS_IN_LINK_RADII * link_radius
    for j, p in enumerate(replay_targets(result)):
        marker = pin.GeometryObject(
            f"target_{j + 1}", 0, pin.SE3(np.eye(3), p), coal.Sphere(radius)
        )
        marker.meshColor = _TARGET_RGBA
        visual.addGeometryObject(marker)
    return ReplayRobot(
        name=chain.name,
        model=chain.model,
        visual_model=visual,
        package_dirs=(),
        tip_frame=chain.tip_frame,
    )


def replay_track(result: IKPathResult, segment_time: float = 1.0) -> tuple[Array, Array]:
    """Knot times and configurations of the replayed cycle.

    Parameters
    ----------
    result : IKPathResult
        The result.
    segment_time : float
        Duration of the move from one target to the next in [s] (> 0).

    Returns
    -------
    t : ndarray, shape (s + 1,)
        ``j * segment_time`` in [s].
    q : ndarray, shape (s + 1, n)
        The configurations in [rad], the first repeated at the end. The
        viewer interpolates linearly in joint space between knots, which is
        :meth:`IKPathResult.joint_path` sampled at the viewer's frame times.

    Raises
    ------
    ParameterError
        If ``segment_time`` is not a positive number.
    """
    dt = _check_segment_time(segment_time)
    path = result.joint_path(samples_per_segment=1)
    return path.s * dt, path.q


def _ghosts(
    result: IKPathResult, others: Sequence[IKPathResult], segment_time: float
) -> list[tuple[Array, Array]]:
    ghosts = []
    for k, other in enumerate(others):
        if other.problem.planar_chain.model.nq != result.problem.planar_chain.model.nq or (
            other.problem.n_targets != result.problem.n_targets
        ):
            raise ParameterError(
                f"others[{k}] has another chain or number of targets than the replayed result",
                name="others",
                value=k,
            )
        ghosts.append(replay_track(other, segment_time))
    return ghosts


def replay_ikpath(
    result: IKPathResult,
    *,
    viewer: meshcat.Visualizer | MeshcatServer | str | None = None,
    segment_time: float = 1.0,
    others: Sequence[IKPathResult] = (),
    realtime: bool = False,
    speed: float = 1.0,
) -> meshcat.Visualizer:
    """Play an IK path in a live meshcat viewer (:func:`youbot_opt.viz.replay`).

    Parameters
    ----------
    result : IKPathResult
        The path to play.
    viewer : meshcat.Visualizer, MeshcatServer, str or None
        Where to draw (see :func:`youbot_opt.viz.replay`); None starts a
        loopback-only server owned by the returned client.
    segment_time : float
        Duration of each move between targets in [s].
    others : sequence of IKPathResult
        Results of the same chain and number of targets drawn as ghosts.
    realtime : bool
        Stream the poses at the pace of the time grid (the call lasts
        ``s * segment_time / speed``) instead of sending a browser-side
        animation (default; the call returns at once).
    speed : float
        Playback speed factor for ``realtime``.

    Returns
    -------
    meshcat.Visualizer
        The client; ``url()`` is the address to open.
    """
    from youbot_opt.viz import replay

    t, q = replay_track(result, segment_time)
    return replay(
        cast("RobotLike", replay_robot(result)),
        t,
        q,
        viewer=viewer,
        frame_path="ikpath",
        targets=replay_targets(result),
        ghosts=_ghosts(result, others, segment_time),
        realtime=realtime,
        speed=speed,
    )


def export_ikpath_html(
    result: IKPathResult,
    path: str | Path,
    *,
    segment_time: float = 1.0,
    others: Sequence[IKPathResult] = (),
    fps: float = 30.0,
) -> Path:
    """Write a standalone HTML file that plays the IK path offline (``viz.export_html``).

    Parameters
    ----------
    result : IKPathResult
        The path to play (in a loop).
    path : str or Path
        The HTML file; its folder must exist.
    segment_time : float
        Duration of each move between targets in [s].
    others : sequence of IKPathResult
        Results of the same chain and number of targets drawn as ghosts.
    fps : float
        Key frames per [s].

    Returns
    -------
    Path
        The file written. Open ``file.html#t=2`` to see the pose at 2 s, paused.
    """
    from youbot_opt.viz import export_html

    t, q = replay_track(result, segment_time)
    return export_html(
        cast("RobotLike", replay_robot(result)),
        t,
        q,
        path,
        fps=fps,
        frame_path="ikpath",
        targets=replay_targets(result),
        ghosts=_ghosts(result, others, segment_time),
    )


def _marker(name: str, placement: pin.SE3, shape: Any, rgba: ArrayLike) -> pin.GeometryObject:
    obj = pin.GeometryObject(name, 0, placement, shape)
    obj.meshColor = np.asarray(rgba, dtype=float)
    return obj


def spatial_replay_robot(result: IKPathResult, robot: RobotLike, size: float = 0.05) -> ReplayRobot:
    """Return the loaded ``robot`` (its visuals) with the targets of ``result`` as markers.

    Parameters
    ----------
    result : IKPathResult
        The path; its problem's model must be ``robot.model`` (same joints).
    robot : RobotLike
        E.g. ``load_model("ur5")``.
    size : float
        Marker size in [m]: sphere radius / 2, triad arm length.

    Raises
    ------
    ParameterError
        If the robot's model has another configuration size than the problem's.
    """
    problem = result.problem
    if robot.model.nq != problem.model.nq:
        raise ParameterError(
            f"robot has nq = {robot.model.nq}, the result's model {problem.model.nq}",
            name="robot",
            value=robot.model.name,
        )
    visual = robot.visual_model.copy()
    rod = 0.06 * size
    for j, target in enumerate(problem.targets):
        p = target.position
        visual.addGeometryObject(
            _marker(f"target_{j + 1}", pin.SE3(np.eye(3), p), coal.Sphere(size / 2), _TARGET_RGBA)
        )
        axes: list[tuple[Array, Sequence[float]]] = []
        if target.rotation is not None:
            axes = [(target.rotation[:, k], rgba) for k, rgba in enumerate(_TRIAD_RGBA)]
        elif target.approach is not None:
            axes = [(target.approach, (0.1, 0.1, 0.1, 1.0))]
        for k, (direction, rgba) in enumerate(axes):
            z = np.asarray(direction, float)
            rot = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), z).toRotationMatrix()
            centre = p + z * (size * 1.5)
            visual.addGeometryObject(
                _marker(
                    f"target_{j + 1}_axis_{k}",
                    pin.SE3(rot, centre),
                    coal.Cylinder(rod, 3 * size),
                    rgba,
                )
            )
    return ReplayRobot(
        name=robot.name,
        model=problem.model,
        visual_model=visual,
        package_dirs=tuple(str(d) for d in robot.package_dirs),
        tip_frame=problem.frame,
    )


_TRIAD_RGBA = ((0.9, 0.1, 0.1, 1.0), (0.1, 0.8, 0.1, 1.0), (0.1, 0.2, 0.9, 1.0))


def spatial_replay_track(
    result: IKPathResult, segment_time: float = 1.0, samples_per_leg: int = 12
) -> tuple[Array, Array]:
    """Return times [s] and Pinocchio configurations (nq) of the replayed cycle.

    Each leg is straight in the active joint angles and sampled
    ``samples_per_leg`` times, so that the viewer's interpolation between
    samples (geodesic on a continuous joint's circle) follows the unwrapped angles.
    """
    dt = _check_segment_time(segment_time)
    q = result.configurations
    closed = np.vstack([q, q[:1]])
    s = q.shape[0]
    u = np.linspace(0.0, float(s), s * samples_per_leg + 1)
    knots = np.arange(s + 1, dtype=float)
    theta = np.column_stack([np.interp(u, knots, closed[:, i]) for i in range(q.shape[1])])
    configs = np.array([result.problem.configuration(th) for th in theta])
    return u * dt, configs


def replay_spatial_ikpath(
    result: IKPathResult,
    robot: RobotLike,
    *,
    viewer: meshcat.Visualizer | MeshcatServer | str | None = None,
    segment_time: float = 1.0,
    realtime: bool = False,
) -> meshcat.Visualizer:
    """Play a spatial IK path in a live meshcat viewer (targets, triads, frame path)."""
    from youbot_opt.viz import replay

    t, q = spatial_replay_track(result, segment_time)
    return replay(
        cast("RobotLike", spatial_replay_robot(result, robot)),
        t,
        q,
        viewer=viewer,
        frame_path="ikpath",
        targets=np.array([tg.position for tg in result.problem.targets]),
        realtime=realtime,
    )


def export_spatial_ikpath_html(
    result: IKPathResult,
    robot: RobotLike,
    path: str | Path,
    *,
    segment_time: float = 1.0,
    fps: float = 30.0,
) -> Path:
    """Write a standalone HTML replay of a spatial IK path (see :func:`replay_spatial_ikpath`)."""
    from youbot_opt.viz import export_html

    t, q = spatial_replay_track(result, segment_time)
    return export_html(
        cast("RobotLike", spatial_replay_robot(result, robot)),
        t,
        q,
        path,
        fps=fps,
        frame_path="ikpath",
        targets=np.array([tg.position for tg in result.problem.targets]),
    )
