"""Meshcat replay of IK-path results: live, or as one standalone HTML file.

An :class:`~youbot_opt.ikpath.result.IKPathResult` is replayed as the cyclic
joint path through its configurations: configuration ``j`` is shown at time
``t_j = j * segment_time`` [s], the first configuration again at
``s * segment_time`` (the cycle closes), and between two targets the joints
move **linearly in joint space** (``pin.interpolate`` of the chain's revolute
joints is linear), the motion whose squared length ``E`` sums. The tip path
is drawn as a line, the targets are marked (red spheres of a size relative to
the arm, part of the scene's robot, plus the viewer's own target markers).
Other results of the same problem (e.g. the distinct minima of a multistart)
can be overlaid as translucent ghosts.

The drawing itself is :mod:`youbot_opt.viz` (:func:`~youbot_opt.viz.replay`,
:func:`~youbot_opt.viz.export_html`); this module turns a result into the
robot, the time grid and the configurations those functions take. The chain
lies in the z = 0 plane of the viewer (its x-y plane is the study's plane).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import coal
import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.ikpath.result import IKPathResult

if TYPE_CHECKING:
    import meshcat

    from youbot_opt.viz.meshcat.scene import RobotLike

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


def replay_targets(result: IKPathResult) -> Array:
    """Targets of ``result`` as points of the viewer, shape (s, 3) in [m] (z = 0)."""
    targets = result.problem.targets
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
    chain = result.problem.chain
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
        if other.problem.chain.model.nq != result.problem.chain.model.nq or (
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
    viewer: Any = None,
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
