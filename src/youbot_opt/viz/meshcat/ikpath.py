"""Meshcat replay of IK-path results: live, or as one standalone HTML file.

Turns an :class:`~youbot_opt.ikpath.result.IKPathResult` into the robot, time
grid and configurations that :func:`~youbot_opt.viz.replay` and
:func:`~youbot_opt.viz.export_html` draw: the cyclic path, linear in joint
space between targets, with the targets and the frame's path marked and other
minima as ghosts. One function per verb whatever the robot: a planar chain is
drawn with its own links in its plane; any other robot (or ``robot=`` given)
on the robot's visuals, pose and axis targets with their axes.
Conventions: docs/design.md, "Module notes".

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


def _on_chain(result: IKPathResult, robot: RobotLike | None) -> bool:
    """Whether ``result`` is drawn on its planar chain (no ``robot`` given, the problem has one)."""
    return robot is None and result.problem.chain is not None


def replay_targets(result: IKPathResult, robot: RobotLike | None = None) -> Array:
    """Targets of ``result`` as points of the viewer, shape (s, 3) in [m].

    On a planar chain (``robot`` None and :attr:`CyclicIKProblem.chain` set)
    the chain's plane coordinates with z = 0; else the targets' positions.
    """
    if _on_chain(result, robot):
        targets = result.problem.target_points
        return np.column_stack([targets, np.zeros(len(targets))])
    return np.array([t.position for t in result.problem.targets], dtype=float)


def _chain_robot(result: IKPathResult) -> ReplayRobot:
    """Return the planar chain's primitive visuals with a sphere at every target."""
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


def _marker(name: str, placement: pin.SE3, shape: Any, rgba: ArrayLike) -> pin.GeometryObject:
    obj = pin.GeometryObject(name, 0, placement, shape)
    obj.meshColor = np.asarray(rgba, dtype=float)
    return obj


_TRIAD_RGBA = ((0.9, 0.1, 0.1, 1.0), (0.1, 0.8, 0.1, 1.0), (0.1, 0.2, 0.9, 1.0))


def _robot_with_targets(result: IKPathResult, robot: RobotLike, size: float) -> ReplayRobot:
    """Return the robot's visuals with the targets as spheres, pose triads, approach rods."""
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


def replay_robot(
    result: IKPathResult, robot: RobotLike | None = None, size: float = 0.05
) -> ReplayRobot:
    """Return what the replay draws: the robot with a visible marker at every target.

    Parameters
    ----------
    result : IKPathResult
        The path.
    robot : RobotLike, optional
        The robot whose visuals to draw (e.g. ``load_model("ur5")``; its model
        must be the problem's, same joints). Default: a planar chain's own
        links (cylinders and spheres), else the problem's
        :class:`~youbot_opt.robot.model.RobotModel` (a problem built on a
        ``pinocchio.Model`` or loaded from a file has no visuals: pass ``robot``).
    size : float
        Marker size in [m] on a robot: sphere radius / 2, triad arm length
        (a planar chain's target spheres are 1.3 link radii, so that they
        scale with the arm; the viewer's own target spheres are 2 cm).

    Returns
    -------
    ReplayRobot
        Name, model, visual model (the robot's visuals + ``target_<j>`` spheres
        and, for pose and axis targets, ``target_<j>_axis_<k>`` rods), package
        directories, the frame.

    Raises
    ------
    ParameterError
        If ``robot`` has another configuration size than the problem's model.
    """
    if _on_chain(result, robot):
        return _chain_robot(result)
    return _robot_with_targets(result, result.problem.robot_model if robot is None else robot, size)


def replay_track(
    result: IKPathResult,
    segment_time: float = 1.0,
    robot: RobotLike | None = None,
    samples_per_leg: int | None = None,
) -> tuple[Array, Array]:
    """Knot times [s] and configurations of the replayed cycle, for :func:`replay_robot`.

    Each leg is straight in the active joint angles (:meth:`IKPathResult.joint_path`).

    Parameters
    ----------
    result : IKPathResult
        The result.
    segment_time : float
        Duration of the move from one target to the next in [s] (> 0).
    robot : RobotLike, optional
        As for :func:`replay_robot`: on a planar chain the configurations are
        the chain's angles, else Pinocchio configurations (nq) of the model.
    samples_per_leg : int, optional
        Samples per leg. Default: 1 on a planar chain (the viewer interpolates
        linearly in joint space between knots, which is the path), 12 on a
        robot (so that the viewer's interpolation, geodesic on a continuous
        joint's circle, follows the unwrapped angles).

    Returns
    -------
    t : ndarray, shape (s * samples_per_leg + 1,)
        In [s]; ``t[k * samples_per_leg] = k * segment_time``.
    q : ndarray, shape (s * samples_per_leg + 1, nq)
        The configurations, the first repeated at the end.

    Raises
    ------
    ParameterError
        If ``segment_time`` is not a positive number.
    """
    dt = _check_segment_time(segment_time)
    on_chain = _on_chain(result, robot)
    if samples_per_leg is None:
        samples_per_leg = 1 if on_chain else 12
    path = result.joint_path(samples_per_segment=samples_per_leg)
    if on_chain:
        return path.s * dt, path.q
    return path.s * dt, np.array([result.problem.configuration(th) for th in path.q])


def _ghosts(
    result: IKPathResult,
    others: Sequence[IKPathResult],
    segment_time: float,
    robot: RobotLike | None,
) -> list[tuple[Array, Array]]:
    ghosts = []
    nq = result.problem.model.nq
    for k, other in enumerate(others):
        if (
            _on_chain(other, robot) != _on_chain(result, robot)
            or other.problem.model.nq != nq
            or other.problem.n_targets != result.problem.n_targets
        ):
            raise ParameterError(
                f"others[{k}] has another chain or number of targets than the replayed result",
                name="others",
                value=k,
            )
        ghosts.append(replay_track(other, segment_time, robot))
    return ghosts


def replay_ikpath(
    result: IKPathResult,
    robot: RobotLike | None = None,
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
    robot : RobotLike, optional
        The robot to draw (see :func:`replay_robot`; default: a planar chain's
        links, else the problem's robot).
    viewer : meshcat.Visualizer, MeshcatServer, str or None
        Where to draw (see :func:`youbot_opt.viz.replay`); None starts a
        loopback-only server owned by the returned client.
    segment_time : float
        Duration of each move between targets in [s].
    others : sequence of IKPathResult
        Results of the same robot and number of targets drawn as ghosts.
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

    t, q = replay_track(result, segment_time, robot)
    return replay(
        cast("RobotLike", replay_robot(result, robot)),
        t,
        q,
        viewer=viewer,
        frame_path="ikpath",
        targets=replay_targets(result, robot),
        ghosts=_ghosts(result, others, segment_time, robot),
        realtime=realtime,
        speed=speed,
    )


def export_ikpath_html(
    result: IKPathResult,
    path: str | Path,
    *,
    robot: RobotLike | None = None,
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
    robot : RobotLike, optional
        The robot to draw (see :func:`replay_robot`).
    segment_time : float
        Duration of each move between targets in [s].
    others : sequence of IKPathResult
        Results of the same robot and number of targets drawn as ghosts.
    fps : float
        Key frames per [s].

    Returns
    -------
    Path
        The file written. Open ``file.html#t=2`` to see the pose at 2 s, paused.
    """
    from youbot_opt.viz import export_html

    t, q = replay_track(result, segment_time, robot)
    return export_html(
        cast("RobotLike", replay_robot(result, robot)),
        t,
        q,
        path,
        fps=fps,
        frame_path="ikpath",
        targets=replay_targets(result, robot),
        ghosts=_ghosts(result, others, segment_time, robot),
    )
