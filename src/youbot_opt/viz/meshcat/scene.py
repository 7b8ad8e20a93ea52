"""The replay scene: trajectories laid out as copies of the robot, their poses, key frames, camera.

Shared by the live replay and the HTML export of :mod:`youbot_opt.viz.meshcat.replay`.
A scene holds one or more runs (trajectories). Each run is a copy of the robot
under its own scene node: the first at the origin, ``extra`` runs side by side
(translated), ``ghosts`` translucent over the first. Between knots,
configurations are interpolated on the configuration space (``pin.interpolate``),
and clamped before the first and after the last knot. The obstacles of a
:class:`~youbot_opt.collision.scene.Scene` go with each copy that shows
targets (world-fixed ones placed once, under the copy's node) and with every
copy for those carried by a robot frame, which move with their frame.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol

import meshcat
import meshcat.animation as ma
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.collision.scene import Obstacle, Scene
from youbot_opt.collision.shapes import HalfSpace
from youbot_opt.exceptions import FrameNotFound, ParameterError
from youbot_opt.viz.meshcat.geometry import obstacle_command, set_object_command

__all__ = [
    "MAX_REPLAY_FRAMES",
    "GHOST_OPACITY",
    "TARGET_RADIUS",
    "RobotLike",
    "Run",
    "check_robot",
    "check_targets",
    "layout_runs",
    "attach_obstacles",
    "frame_times",
    "ee_points",
    "scene_points",
    "build_scene",
    "show_at",
    "animation",
    "set_camera",
    "side_by_side_spacing",
    "PLANAR_SPACING",
]

GHOST_OPACITY = 0.35  # [-] opacity of ghost copies
TARGET_RADIUS = 0.02  # [m] radius of the target spheres
SPACING_IN_REACHES = 2.2  # [-] default distance between side-by-side copies, in arm reaches
PLANAR_SPACING = 1.3  # [-] distance between copies of a planar motion, in its in-plane extent
_PALETTE = (0xE4572E, 0x17BEBB, 0x76B041, 0xFFC914, 0x8E44AD, 0x2E86AB)  # end-effector paths
_TARGET_COLOR = 0xD62728
_ELEVATION = np.deg2rad(25.0)  # [rad] of the camera above the scene's best-fit plane
_DISTANCE_IN_RADII = 1.9  # [-] camera distance from its target, in scene radii


class RobotLike(Protocol):
    """What replay needs of a robot (``youbot_opt.robot.model.RobotModel`` has it).

    Read-only members, so that frozen dataclasses and read-only properties
    (``RobotModel.name``, ``RobotModel.package_dirs``) satisfy it.
    """

    @property
    def name(self) -> str:
        """Scene name of the robot."""

    @property
    def model(self) -> pin.Model:
        """Kinematic model."""

    @property
    def visual_model(self) -> pin.GeometryModel:
        """Visual geometry."""

    @property
    def package_dirs(self) -> Sequence[str | Path]:
        """Directories that ``package://`` mesh paths resolve against."""

    @property
    def tip_frame(self) -> str:
        """Frame whose path is drawn."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Run:
    """One trajectory of the scene and how it is drawn.

    Attributes
    ----------
    node : str
        Scene path of this copy of the robot.
    t : ndarray, shape (N,)
        Knot times in [s], strictly increasing.
    q : ndarray, shape (N, nq)
        Configurations at the knots in [rad].
    offset : ndarray, shape (3,)
        Translation of the copy in [m].
    opacity : float
        Opacity of the copy, 1 for opaque.
    color : int
        RGB colour (``0xRRGGBB``) of its end-effector path.
    with_targets : bool
        Whether the targets are drawn with this copy.
    world : tuple of Obstacle
        World-fixed obstacles drawn with this copy (placed once).
    carried : tuple of (Obstacle, int)
        Obstacles carried by a robot frame, with the frame's index: they move with it.
    """

    node: str
    t: Array
    q: Array
    offset: Array
    opacity: float
    color: int
    with_targets: bool
    world: tuple[Obstacle, ...] = ()
    carried: tuple[tuple[Obstacle, int], ...] = ()


def check_robot(robot: RobotLike) -> None:
    """Check that ``robot`` has the attributes replay needs and that its tip frame exists.

    Raises
    ------
    ParameterError
        If an attribute is missing.
    FrameNotFound
        If ``robot.tip_frame`` is not a frame of ``robot.model``.
    """
    for attr in ("name", "model", "visual_model", "package_dirs", "tip_frame"):
        if not hasattr(robot, attr):
            raise ParameterError(
                f"robot must have .{attr} (a youbot_opt RobotModel has it); "
                f"got a {type(robot).__name__} without it",
                name="robot",
            )
    if not robot.model.existFrame(robot.tip_frame):
        raise FrameNotFound(robot.tip_frame, tuple(f.name for f in robot.model.frames))


def _check_track(model: pin.Model, t: object, q: object, name: str) -> tuple[Array, Array]:
    t_arr = np.array(t, dtype=float)
    q_arr = np.array(q, dtype=float)
    if t_arr.ndim != 1 or t_arr.size == 0 or not np.all(np.isfinite(t_arr)):
        raise ParameterError(
            f"{name}: t must be a non-empty finite (N,) array in [s], got shape {t_arr.shape}",
            name="t",
        )
    if np.any(np.diff(t_arr) <= 0):
        raise ParameterError(f"{name}: t must be strictly increasing", name="t", value=t_arr)
    if q_arr.shape != (t_arr.size, model.nq) or not np.all(np.isfinite(q_arr)):
        raise ParameterError(
            f"{name}: q must be a finite array of shape (N, nq) = ({t_arr.size}, {model.nq}), "
            f"got {q_arr.shape}",
            name="q",
            value=q_arr.shape,
        )
    return t_arr, q_arr


def check_targets(targets: object) -> Array | None:
    """Return ``targets`` as a finite (K, 3) array in [m], or None.

    Raises
    ------
    ParameterError
        If the shape is not (K, 3) or a value is not finite.
    """
    if targets is None:
        return None
    arr = np.array(targets, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3 or not np.all(np.isfinite(arr)):
        raise ParameterError(
            f"targets must be a finite (K, 3) array of positions in [m], got shape {arr.shape}",
            name="targets",
        )
    return arr


def _node_name(label: str, taken: Sequence[str] = ()) -> str:
    name = re.sub(r"[^A-Za-z0-9_.\-]+", "_", label).strip("_") or "run"
    while name in taken:
        name += "_"
    return name


def layout_runs(
    robot: RobotLike,
    t: object,
    q: object,
    *,
    ghosts: Sequence[tuple[object, object]],
    extra: Sequence[tuple[object, object, str]],
    spacing: object,
    root: str,
    label: str | None = None,
) -> list[Run]:
    """Validate every trajectory and place the copies.

    Parameters
    ----------
    robot : RobotLike
        The robot.
    t, q : array_like, shapes (N,) and (N, nq)
        The main trajectory: times in [s], configurations in [rad].
    ghosts : sequence of (t, q)
        Trajectories drawn translucent over the main one.
    extra : sequence of (t, q, label)
        Trajectories drawn side by side with the main one.
    spacing : array_like, shape (3,), or None
        Offset in [m] between neighbouring copies; by default
        :data:`SPACING_IN_REACHES` times the largest tip distance from the base,
        along y. The copies are centred on the origin.
    root : str
        Scene path under which the copies are placed.
    label : str, optional
        Scene name of the main copy; default: the robot's name.

    Returns
    -------
    list of Run
        The main run, then the ghosts, then the extra runs.
    """
    main = _check_track(robot.model, t, q, "trajectory")
    ghost_tracks = [
        _check_track(robot.model, g[0], g[1], f"ghosts[{i}]") for i, g in enumerate(ghosts)
    ]
    extra_tracks = [
        _check_track(robot.model, e[0], e[1], f"extra[{i}]") for i, e in enumerate(extra)
    ]
    if spacing is None:
        reach = max(
            float(np.max(np.linalg.norm(ee_points(robot, tk, qk, tk), axis=1)))
            for tk, qk in [main, *ghost_tracks, *extra_tracks]
        )
        step = np.array([0.0, SPACING_IN_REACHES * max(reach, 0.25), 0.0])  # [m]
    else:
        step = np.array(spacing, dtype=float)
        if step.shape != (3,) or not np.all(np.isfinite(step)):
            raise ParameterError("spacing must be a finite (3,) vector in [m]", name="spacing")
    offsets = [(k - len(extra) / 2.0) * step for k in range(1 + len(extra))]
    names = [_node_name(robot.name if label is None else str(label))]
    runs = [Run(node=f"{root}/{names[0]}", t=main[0], q=main[1], offset=offsets[0],
                opacity=1.0, color=_PALETTE[0], with_targets=True)]  # fmt: skip
    for i, (tk, qk) in enumerate(ghost_tracks):
        color = _PALETTE[(1 + i) % len(_PALETTE)]
        runs.append(Run(node=f"{root}/ghost_{i}", t=tk, q=qk, offset=offsets[0],
                        opacity=GHOST_OPACITY, color=color, with_targets=False))  # fmt: skip
    for k, ((tk, qk), item) in enumerate(zip(extra_tracks, extra, strict=True), start=1):
        names.append(
            _node_name(str(item[2]), [*names, *(f"ghost_{i}" for i in range(len(ghosts)))])
        )
        color = _PALETTE[(len(ghosts) + k) % len(_PALETTE)]
        runs.append(Run(node=f"{root}/{names[-1]}", t=tk, q=qk, offset=offsets[k],
                        opacity=1.0, color=color, with_targets=True))  # fmt: skip
    return runs


def attach_obstacles(robot: RobotLike, runs: Sequence[Run], obstacles: Scene | None) -> list[Run]:
    """Give the runs the obstacles of ``obstacles`` to draw.

    World-fixed obstacles go with the runs that show targets (the main copy and
    the side-by-side ones, not the ghosts); carried ones with every run.

    Raises
    ------
    ParameterError
        If ``obstacles`` is not a Scene or None.
    FrameNotFound
        If an obstacle is carried by a frame the robot does not have.
    """
    if obstacles is None:
        return list(runs)
    if not isinstance(obstacles, Scene):
        raise ParameterError(
            f"obstacles must be a Scene or None, got a {type(obstacles).__name__}",
            name="obstacles",
        )
    world = tuple(o for o in obstacles.obstacles if o.frame is None)
    carried = tuple(
        (o, _frame_index(robot, o.frame)) for o in obstacles.obstacles if o.frame is not None
    )
    return [replace(run, world=world if run.with_targets else (), carried=carried) for run in runs]


def side_by_side_spacing(robot: RobotLike, tracks: Sequence[tuple[Array, Array]]) -> Array:
    """Offset in [m] between side-by-side copies that keeps a planar motion face on.

    A motion whose joint origins and tip stay in one vertical plane (the
    youBot's x-z plane) is spaced along the plane's horizontal direction
    (positive x first), so that the camera, which looks along the plane's
    normal, sees every copy face on, by :data:`PLANAR_SPACING` times the
    motion's extent along that direction. Any other motion is spaced along y
    by :data:`SPACING_IN_REACHES` times the largest tip distance from the base
    (the default of :func:`layout_runs`).

    Parameters
    ----------
    robot : RobotLike
        The robot.
    tracks : sequence of (t, q)
        The trajectories: times in [s], configurations in [rad].

    Returns
    -------
    ndarray, shape (3,)
        The spacing, for the ``spacing`` argument of :func:`layout_runs`.
    """
    reach = max(float(np.max(np.linalg.norm(ee_points(robot, t, q, t), axis=1))) for t, q in tracks)
    points = np.concatenate([scene_points(robot, [_track_run(t, q)], t)[1:] for t, q in tracks])
    singular, axes = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)[1:]
    normal = axes[-1]
    if singular[-1] <= 1e-6 * max(singular[0], 1e-12) and abs(normal[2]) < 0.5:
        direction = np.cross(normal, [0.0, 0.0, 1.0])
        direction /= np.linalg.norm(direction)
        if direction[0] < -1e-9 or (abs(direction[0]) <= 1e-9 and direction[1] < 0):
            direction = -direction
        extent = float(np.ptp(points @ direction))  # [m]
        return PLANAR_SPACING * max(extent, 0.25) * direction
    return np.array([0.0, SPACING_IN_REACHES * max(reach, 0.25), 0.0])


def _track_run(t: Array, q: Array) -> Run:
    """Make a bare run at the origin, to measure a track."""
    return Run(node="", t=np.asarray(t, dtype=float), q=np.asarray(q, dtype=float),
               offset=np.zeros(3), opacity=1.0, color=0, with_targets=False)  # fmt: skip


MAX_REPLAY_FRAMES = 36_000
"""Most key frames of one replay: 20 min at 30 frames/s (each frame holds every body's pose)."""


def frame_times(runs: Sequence[Run], fps: float) -> Array:
    """Key-frame times in [s]: every ``1 / fps`` from the earliest start, and the latest end.

    Raises
    ------
    ParameterError
        If the motion needs more than :data:`MAX_REPLAY_FRAMES` frames at ``fps``
        (``name="replay_frames"``; the message names the duration and the limit).
    """
    start = min(float(run.t[0]) for run in runs)
    stop = max(float(run.t[-1]) for run in runs)
    frames = (stop - start) * fps
    if not frames <= MAX_REPLAY_FRAMES:
        raise ParameterError(
            f"a replay of {stop - start:.6g} s at {fps:g} frames/s needs {frames:.3g} frames, "
            f"more than MAX_REPLAY_FRAMES = {MAX_REPLAY_FRAMES}; replay a shorter motion or "
            "lower the frame rate",
            name="replay_frames",
            value=frames,
        )
    grid = start + np.arange(int(np.floor((stop - start) * fps)) + 1) / fps
    return np.append(grid[grid < stop - 1e-9], stop)


def _sample(model: pin.Model, t: Array, q: Array, times: Array) -> Array:
    """Interpolate the configurations at ``times`` [s] on the configuration space, clamped."""
    if t.size == 1:
        return np.repeat(q, times.size, axis=0)
    k = np.clip(np.searchsorted(t, times, side="right") - 1, 0, t.size - 2)
    alpha = np.clip((times - t[k]) / (t[k + 1] - t[k]), 0.0, 1.0)
    return np.array(
        [pin.interpolate(model, q[i], q[i + 1], a) for i, a in zip(k, alpha, strict=True)]
    )


def _tip_frame_id(robot: RobotLike) -> int:
    """Index of the tip frame; a link's frame when a fixed joint shares its name (z1)."""
    return _frame_index(robot, robot.tip_frame)


def _frame_index(robot: RobotLike, name: str) -> int:
    """Index of frame ``name``; a link's frame when a fixed joint shares its name (z1)."""
    frames = robot.model.frames
    matches = [i for i in range(len(frames)) if frames[i].name == name]
    if not matches:
        raise FrameNotFound(name, tuple(f.name for f in frames))
    bodies = [i for i in matches if frames[i].type == pin.FrameType.BODY]
    return int((bodies or matches)[0])


def ee_points(robot: RobotLike, t: Array, q: Array, times: Array) -> Array:
    """Compute the tip positions in [m] at ``times`` [s], shape (len(times), 3), base frame."""
    model, data = robot.model, robot.model.createData()
    frame_id = _tip_frame_id(robot)
    points = []
    for qk in _sample(model, t, q, times):
        pin.forwardKinematics(model, data, qk)
        points.append(pin.updateFramePlacement(model, data, frame_id).translation.copy())
    return np.array(points)


def scene_points(robot: RobotLike, runs: Sequence[Run], times: Array) -> Array:
    """List the points in [m] the camera should see: joint origins and tips at ``times`` [s].

    Returns
    -------
    ndarray, shape (M, 3)
        The points, with each copy's offset applied, and the origin.
    """
    model, data = robot.model, robot.model.createData()
    frame_id = _tip_frame_id(robot)
    points = [np.zeros(3)]
    for run in runs:
        for qk in _sample(model, run.t, run.q, times):
            pin.forwardKinematics(model, data, qk)
            points += [placement.translation + run.offset for placement in data.oMi]
            points.append(pin.updateFramePlacement(model, data, frame_id).translation + run.offset)
        points += [
            o.translation + run.offset for o in run.world if not isinstance(o.shape, HalfSpace)
        ]
    return np.array(points)


def _geometry_poses(robot: RobotLike, run: Run, q: Array) -> list[Array]:
    """Poses (4, 4) at ``q`` of the visual geometry objects, then of ``run``'s carried obstacles."""
    model, data = robot.model, robot.model.createData()
    gdata = robot.visual_model.createData()
    pin.forwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, robot.visual_model, gdata)
    poses = [gdata.oMg[i].homogeneous.copy() for i in range(robot.visual_model.ngeoms)]
    for obstacle, frame_id in run.carried:
        frame = pin.updateFramePlacement(model, data, frame_id).homogeneous
        poses.append(frame @ _pose(obstacle))
    return poses


def _pose(obstacle: Obstacle) -> Array:
    """Pose (4, 4) of an obstacle's shape frame in its parent frame (world or carrying)."""
    matrix = np.eye(4)
    matrix[:3, :3] = obstacle.rotation
    matrix[:3, 3] = obstacle.translation
    return matrix


def _translation(offset: Array) -> Array:
    matrix = np.eye(4)
    matrix[:3, 3] = offset
    return matrix


def build_scene(
    vis: meshcat.Visualizer,
    robot: RobotLike,
    runs: Sequence[Run],
    *,
    ee_path: bool,
    targets: Array | None,
    ee_times: Array,
) -> list[list[str]]:
    """Send the objects of every run: robot copy, obstacles, end-effector path, targets.

    Parameters
    ----------
    vis : meshcat.Visualizer
        Where to send them (a live client or a recorder).
    robot : RobotLike
        The robot.
    runs : sequence of Run
        The copies.
    ee_path : bool
        Draw each run's tip path as a line.
    targets : ndarray, shape (K, 3), or None
        Targets in [m], drawn as spheres with the runs that show targets.
    ee_times : ndarray
        Times in [s] at which the tip path is sampled, besides the knots.

    Returns
    -------
    list of list of str
        Per run, the scene path of each visual geometry object, then of each
        carried obstacle.
    """
    nodes = []
    triangles: dict[tuple[object, ...], object] = {}  # shared by the copies of the robot
    for run in runs:
        vis[run.node].set_transform(_translation(run.offset))
        run_nodes: list[str] = []
        names: list[str] = []
        for go in robot.visual_model.geometryObjects:
            names.append(_node_name(go.name, names))
            node = f"{run.node}/visuals/{names[-1]}"
            command = set_object_command(
                go, robot.package_dirs, run.opacity, vis[node].path, triangles=triangles
            )
            vis.window.send(command)
            run_nodes.append(node)
        taken: list[str] = []
        for obstacle in run.world:  # placed once
            taken.append(_node_name(obstacle.name, taken))
            node = f"{run.node}/obstacles/{taken[-1]}"
            vis.window.send(obstacle_command(obstacle.shape, vis[node].path))
            vis[node].set_transform(_pose(obstacle))
        for obstacle, _ in run.carried:  # posed with the robot, key frame by key frame
            taken.append(_node_name(obstacle.name, taken))
            node = f"{run.node}/carried/{taken[-1]}"
            vis.window.send(obstacle_command(obstacle.shape, vis[node].path))
            run_nodes.append(node)
        nodes.append(run_nodes)
        if ee_path:
            points = ee_points(robot, run.t, run.q, np.union1d(run.t, ee_times))
            material = mg.LineBasicMaterial(color=run.color, opacity=run.opacity)
            line = mg.Line(mg.PointsGeometry(points.T.astype(np.float32)), material)
            vis[f"{run.node}/ee_path"].set_object(line)
        if targets is not None and run.with_targets:
            material = mg.MeshPhongMaterial(color=_TARGET_COLOR)
            for k, target in enumerate(targets):
                vis[f"{run.node}/targets/{k}"].set_object(mg.Sphere(TARGET_RADIUS), material)
                vis[f"{run.node}/targets/{k}"].set_transform(_translation(target))
    return nodes


def show_at(
    vis: meshcat.Visualizer,
    robot: RobotLike,
    runs: Sequence[Run],
    nodes: list[list[str]],
    time_s: float,
) -> None:
    """Send the pose of every geometry object of every run at time ``time_s`` [s]."""
    for run, run_nodes in zip(runs, nodes, strict=True):
        q = _sample(robot.model, run.t, run.q, np.array([time_s]))[0]
        for node, pose in zip(run_nodes, _geometry_poses(robot, run, q), strict=True):
            vis[node].set_transform(pose)


def animation(
    vis: meshcat.Visualizer,
    robot: RobotLike,
    runs: Sequence[Run],
    nodes: list[list[str]],
    times: Array,
    fps: float,
) -> ma.Animation:
    """Key frames of every geometry object at ``times`` [s].

    The key frame of time ``t`` is frame ``(t - times[0]) * fps`` of a clip
    played at ``fps`` frames per [s], so the clip time is ``t - times[0]`` in
    [s] whatever the spacing of ``times``.

    Returns
    -------
    meshcat.animation.Animation
        The animation, to be sent with ``vis.set_animation``.
    """
    result = ma.Animation(default_framerate=fps)
    frames = ((np.asarray(times, dtype=float) - times[0]) * fps).tolist()
    for run, run_nodes in zip(runs, nodes, strict=True):
        # (frames, objects, 4, 4): each object's poses over the clip, one track each
        poses = np.array(
            [_geometry_poses(robot, run, q) for q in _sample(robot.model, run.t, run.q, times)]
        )
        if poses.shape[1] != len(run_nodes):
            raise ValueError(f"{poses.shape[1]} poses for {len(run_nodes)} scene nodes")
        for k, node in enumerate(run_nodes):
            clip = ma.AnimationClip(fps=fps)
            clip.tracks["position"] = ma.AnimationTrack(
                "position", "vector3", list(frames), poses[:, k, :3, 3].tolist()
            )
            clip.tracks["quaternion"] = ma.AnimationTrack(
                "quaternion",
                "quaternion",
                list(frames),
                _three_quaternions(poses[:, k, :3, :3]).tolist(),
            )
            result.clips[vis[node].path] = clip
    return result


def _three_quaternions(rotations: Array) -> Array:
    """Quaternions ``(x, y, z, w)`` of rotation matrices ``(n, 3, 3)``, as meshcat keys them.

    The order is three.js's; the sign is meshcat's (``w >= 0``, as
    ``meshcat.animation.js_quaternion``), so consecutive keys interpolate as before.
    """
    quaternions = np.array([pin.Quaternion(r).coeffs() for r in rotations]).reshape(-1, 4)
    quaternions[quaternions[:, 3] < 0.0] *= -1.0
    return quaternions


def set_camera(vis: meshcat.Visualizer, points: Array, *, centred: bool) -> Array:
    """Place the camera so that it sees ``points`` [m], shape (M, 3).

    The camera looks at the orbit target, from twice the largest distance of
    a point from the target, along the normal of the points' best-fit plane
    (a planar arm is seen face on), raised by :data:`_ELEVATION`.

    Parameters
    ----------
    vis : meshcat.Visualizer
        The viewer.
    points : ndarray, shape (M, 3)
        Points to see, in [m].
    centred : bool
        True: the caller will move the orbit target to the centre of the
        points' bounding box (the HTML page does). False: the target stays at
        meshcat's origin (a live viewer cannot move it).

    Returns
    -------
    ndarray, shape (3,)
        The orbit target in [m], in meshcat's z-up world frame.
    """
    target = (points.min(axis=0) + points.max(axis=0)) / 2.0 if centred else np.zeros(3)
    radius = max(float(np.max(np.linalg.norm(points - target, axis=1))), 0.2)  # [m]
    normal = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)[2][-1]
    horizontal = np.array([normal[0], normal[1], 0.0])
    if np.linalg.norm(horizontal) < 1e-6:
        horizontal = np.array([1.0, 0.0, 0.0])
    horizontal /= np.linalg.norm(horizontal)
    if horizontal @ np.array([0.3, -1.0, 0.0]) < 0:  # prefer the -y side: x to the right
        horizontal = -horizontal
    direction = np.cos(_ELEVATION) * horizontal + np.array([0.0, 0.0, np.sin(_ELEVATION)])
    eye = target + _DISTANCE_IN_RADII * radius * direction
    # The camera's frame is three.js's y-up world: meshcat's (x, y, z) is (x, z, -y) there.
    vis["/Cameras/default/rotated/<object>"].set_property("position", [eye[0], eye[2], -eye[1]])
    return target
