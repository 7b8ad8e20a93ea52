"""The collision model the optimisers use: the links' bounding balls, the scene, the pairs.

:func:`build_collision_model` fits each link geometry's balls (cached), places
the obstacles on the world or on their carrying joint and lists the checked
pairs. :meth:`CollisionModel.distance_function` is a CasADi Function of the
joints' world placements (``SymbolicModel.forward_kinematics``'s layout): the
optimiser composes it with its own symbolic kinematics once. Apart, a pair's
distance is at most coal's (:mod:`.exact`) and within its ``tolerance`` of it.

>>> d = build_collision_model(robot, scene).distances(robot, q)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np
import pinocchio as pin

from youbot_opt._checks import check_nonnegative
from youbot_opt._typing import Array
from youbot_opt.collision import distance as dist
from youbot_opt.collision.pairs import CollisionPairs, self_collision_pairs
from youbot_opt.collision.scene import Obstacle, Scene
from youbot_opt.collision.shapes import Box, Capsule, Cylinder, Mesh, Sphere
from youbot_opt.collision.spheres import SphereFit, fit_spheres, geometry_hull, hull_points
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel, as_configuration

__all__ = [
    "DEFAULT_TAU",
    "CollisionModel",
    "LinkBalls",
    "PlacedObstacle",
    "build_collision_model",
    "joint_placements",
]

#: Smoothing length of the soft minimum over ball pairs, in [m].
DEFAULT_TAU = 1e-3


@dataclass(frozen=True, slots=True, kw_only=True)
class LinkBalls:
    """The bounding balls of one collision geometry of the robot.

    Attributes
    ----------
    name : str
        The geometry's name (``GeometryObject.name``).
    link : str
        The link (body frame) it belongs to.
    joint : int
        Its parent joint's index (0: the universe).
    centers : ndarray, shape (k, 3)
        Ball centres in [m] in the parent joint's frame.
    radii : ndarray, shape (k,)
        Radii in [m].
    overshoot : float
        The fit's overshoot bound in [m] (:class:`~.spheres.SphereFit`).
    """

    name: str
    link: str
    joint: int
    centers: Array
    radii: Array
    overshoot: float


@dataclass(frozen=True, slots=True, kw_only=True)
class PlacedObstacle:
    """An obstacle placed on a joint of the robot (0: the world).

    Attributes
    ----------
    obstacle : Obstacle
        The scene's obstacle.
    joint : int
        The joint carrying it (0: fixed to the world).
    rotation : ndarray, shape (3, 3)
        Its frame's rotation in the joint's frame.
    translation : ndarray, shape (3,)
        Its frame's position in [m] in the joint's frame.
    balls : SphereFit or None
        Bounding balls (in its own frame) of a mesh obstacle; None for primitives.
    """

    obstacle: Obstacle
    joint: int
    rotation: Array
    translation: Array
    balls: SphereFit | None = None


@dataclass(frozen=True, slots=True, kw_only=True)
class CollisionModel:
    """Bounding balls, obstacles and checked pairs of one robot in one scene.

    Attributes
    ----------
    robot : str
        The robot's name.
    n_joints : int
        Joints of the model without the universe (columns of ``translations``).
    links : tuple of LinkBalls
        One per collision geometry of the robot.
    obstacles : tuple of PlacedObstacle
        The scene's obstacles.
    self_pairs : tuple of (int, int)
        Checked pairs of indices into ``links``.
    scene_pairs : tuple of (int, int)
        Checked pairs (index into ``links``, index into ``obstacles``).
    tau : float
        Soft-minimum smoothing length in [m].
    pairs : CollisionPairs or None
        The self-collision pairs and why the others are left out.
    """

    robot: str
    n_joints: int
    links: tuple[LinkBalls, ...]
    obstacles: tuple[PlacedObstacle, ...]
    self_pairs: tuple[tuple[int, int], ...]
    scene_pairs: tuple[tuple[int, int], ...]
    tau: float = DEFAULT_TAU
    pairs: CollisionPairs | None = None

    @property
    def n_pairs(self) -> int:
        """Number of checked pairs (self pairs first, then link-obstacle pairs)."""
        return len(self.self_pairs) + len(self.scene_pairs)

    @property
    def pair_names(self) -> tuple[tuple[str, str], ...]:
        """Names of the checked pairs, in output order (geometry, geometry or obstacle)."""
        own = tuple((self.links[a].name, self.links[b].name) for a, b in self.self_pairs)
        scene = tuple(
            (self.links[a].name, self.obstacles[o].obstacle.name) for a, o in self.scene_pairs
        )
        return own + scene

    def _ball_counts(self, a: int, b: int | None, obstacle: int | None) -> int:
        n = len(self.links[a].radii)
        if b is not None:
            return n * len(self.links[b].radii)
        balls = self.obstacles[obstacle].balls if obstacle is not None else None
        return n * (len(balls.radii) if balls is not None else 1)

    @property
    def tolerance(self) -> Array:
        """Per pair, how far in [m] the model's distance may lie below the exact one.

        The fits' overshoots, the norm smoothing and the soft minimum's ``tau
        log n``. For a separated pair, ``exact - tolerance <= model <= exact``;
        for a touching or penetrating pair the model's distance is negative.
        """
        out = []
        for a, b in self.self_pairs:
            n = self._ball_counts(a, b, None)
            over = self.links[a].overshoot + self.links[b].overshoot
            out.append(over + dist.NORM_EPS + self.tau * np.log(n))
        for a, o in self.scene_pairs:
            n = self._ball_counts(a, None, o)
            balls = self.obstacles[o].balls
            over = self.links[a].overshoot + (balls.overshoot if balls is not None else 0.0)
            out.append(over + 2 * dist.NORM_EPS + self.tau * np.log(n))
        return np.array(out, dtype=float)

    def distance_function(self) -> ca.Function:
        """Return the Function of the joints' world placements -> pair distances [m].

        Returns
        -------
        casadi.Function
            ``"collision_distances"``: ``rotations`` (3, 3 n_joints) (joint k's
            world rotation in columns 3(k-1)..3(k-1)+2) and ``translations``
            (3, n_joints) [m] (joint k in column k-1), the outputs of
            ``SymbolicModel.forward_kinematics``, -> ``distance`` (n_pairs,) [m],
            in the order of :attr:`pair_names`.
        """
        n = self.n_joints
        rotations = ca.SX.sym("rotations", 3, 3 * n)
        translations = ca.SX.sym("translations", 3, n)

        def placement(joint: int) -> tuple[ca.SX, ca.SX]:
            if joint == 0:
                return ca.SX.eye(3), ca.SX.zeros(3)
            return rotations[:, 3 * (joint - 1) : 3 * joint], translations[:, joint - 1]

        def world_balls(link: LinkBalls) -> list[ca.SX]:
            rot, pos = placement(link.joint)
            return [rot @ ca.DM(c) + pos for c in link.centers]

        centres = [world_balls(link) for link in self.links]
        out: list[ca.SX] = []
        for a, b in self.self_pairs:
            la, lb = self.links[a], self.links[b]
            values = [
                dist.point_point_distance(ca_, cb) - ra - rb
                for ca_, ra in zip(centres[a], la.radii, strict=True)
                for cb, rb in zip(centres[b], lb.radii, strict=True)
            ]
            out.append(dist.soft_min(ca.vertcat(*values), self.tau))
        for a, o in self.scene_pairs:
            out.append(self._link_obstacle(centres[a], self.links[a].radii, o, placement))
        result = ca.vertcat(*out) if out else ca.SX(0, 1)
        return ca.Function(
            "collision_distances",
            [rotations, translations],
            [result],
            ["rotations", "translations"],
            ["distance"],
            {"cse": True},
        )

    def configuration_function(self, forward_kinematics: ca.Function) -> ca.Function:
        """Return the Function q -> pair distances [m], composed with a kinematics Function once.

        The one place where the distances meet the optimisers' symbolic
        kinematics (this package cannot import :mod:`youbot_opt.dynamics`, a
        sibling of its layer, so the caller passes the Function in).

        Parameters
        ----------
        forward_kinematics : casadi.Function
            ``q (nq,) -> rotations (3, 3 n_joints), translations (3, n_joints)``,
            e.g. ``build_symbolic_model(robot).forward_kinematics``.

        Returns
        -------
        casadi.Function
            ``"collision_distances_q"``: ``q`` -> ``distance`` (n_pairs,) [m].

        Raises
        ------
        ParameterError
            The Function's outputs do not have the joints' layout.
        """
        n = self.n_joints
        shapes = [forward_kinematics.size_out(i) for i in range(forward_kinematics.n_out())]
        if shapes[:2] != [(3, 3 * n), (3, n)]:
            raise ParameterError(
                f"forward_kinematics must return rotations (3, {3 * n}) and translations "
                f"(3, {n}), got {shapes}",
                name="forward_kinematics",
                value=shapes,
            )
        q = ca.SX.sym("q", forward_kinematics.size1_in(0))
        rotations, translations = forward_kinematics(q)[:2]
        d = self.distance_function()(rotations, translations)
        return ca.Function("collision_distances_q", [q], [d], ["q"], ["distance"], {"cse": True})

    def _link_obstacle(
        self,
        centres: list[ca.SX],
        radii: Array,
        index: int,
        placement: Callable[[int], tuple[ca.SX, ca.SX]],
    ) -> ca.SX:
        placed = self.obstacles[index]
        rot_j, pos_j = placement(placed.joint)
        rot = rot_j @ ca.DM(placed.rotation)
        pos = rot_j @ ca.DM(placed.translation) + pos_j
        shape = placed.obstacle.shape
        values: list[ca.SX] = []
        for c, r in zip(centres, radii, strict=True):
            local = rot.T @ (c - pos)
            if placed.balls is not None:
                for bc, br in zip(placed.balls.centers, placed.balls.radii, strict=True):
                    values.append(dist.point_point_distance(local, ca.DM(bc)) - br - r)
                continue
            if isinstance(shape, Sphere):
                d = dist.smooth_norm(local) - shape.radius
            elif isinstance(shape, Box):
                d = dist.point_box_distance(local, np.array(shape.size) / 2)
            elif isinstance(shape, Cylinder):
                d = dist.point_cylinder_distance(local, shape.radius, shape.length / 2)
            elif isinstance(shape, Capsule):
                d = dist.point_capsule_distance(local, shape.radius, shape.length / 2)
            else:
                d = dist.point_halfspace_distance(local)
            values.append(d - r)
        return dist.soft_min(ca.vertcat(*values), self.tau)

    def distances(self, robot: RobotModel, q: Array) -> Array:
        """Return the pair distances [m] at configuration ``q`` (Pinocchio's coordinates).

        Builds :meth:`distance_function` on each call: for many configurations
        build it once and evaluate it on :func:`joint_placements`.

        Parameters
        ----------
        robot : RobotModel
            The robot the model was built for.
        q : ndarray, shape (nq,)
            Configuration in [rad] or [m].

        Returns
        -------
        ndarray, shape (n_pairs,)
            Distances in [m], in the order of :attr:`pair_names`.
        """
        rotations, translations = joint_placements(robot, q)
        return np.asarray(self.distance_function()(rotations, translations), dtype=float).ravel()


def joint_placements(robot: RobotModel, q: Array) -> tuple[Array, Array]:
    """Return the joints' world placements at ``q`` in the layout of the distance Function.

    Parameters
    ----------
    robot : RobotModel
        The robot.
    q : ndarray, shape (nq,)
        Configuration (Pinocchio's coordinates) in [rad] or [m].

    Returns
    -------
    rotations : ndarray, shape (3, 3 n_joints)
    translations : ndarray, shape (3, n_joints)
        In [m].
    """
    qa = as_configuration(robot, q)
    data = robot.create_data()
    pin.forwardKinematics(robot.model, data, qa)
    n = robot.model.njoints - 1
    rotations = (
        np.hstack([data.oMi[k].rotation for k in range(1, n + 1)]) if n else np.zeros((3, 0))
    )
    translations = (
        np.column_stack([data.oMi[k].translation for k in range(1, n + 1)])
        if n
        else np.zeros((3, 0))
    )
    return rotations, translations


def _link_balls(robot: RobotModel, cache: bool) -> tuple[LinkBalls, ...]:
    out = []
    for geom in robot.collision_model.geometryObjects:
        fit = fit_spheres(geometry_hull(geom.geometry), cache=cache)
        placed = fit.placed(geom.placement.rotation, geom.placement.translation)
        out.append(
            LinkBalls(
                name=geom.name,
                link=robot.model.frames[geom.parentFrame].name,
                joint=int(geom.parentJoint),
                centers=placed.centers,
                radii=placed.radii,
                overshoot=placed.overshoot,
            )
        )
    return tuple(out)


def _place(robot: RobotModel, obstacle: Obstacle, cache: bool) -> PlacedObstacle:
    rot, pos = obstacle.rotation, obstacle.translation
    joint = 0
    if obstacle.frame is not None:
        frame = robot.model.frames[robot.frame_id(obstacle.frame)]
        joint = int(frame.parentJoint)
        rot, pos = (
            frame.placement.rotation @ rot,
            frame.placement.rotation @ pos + frame.placement.translation,
        )
    balls = (
        fit_spheres(hull_points(obstacle.shape), cache=cache)
        if isinstance(obstacle.shape, Mesh)
        else None
    )
    return PlacedObstacle(
        obstacle=obstacle, joint=joint, rotation=rot, translation=pos, balls=balls
    )


def build_collision_model(
    robot: RobotModel,
    scene: Scene | None = None,
    *,
    self_collision: bool = True,
    pairs: CollisionPairs | None = None,
    tau: float = DEFAULT_TAU,
    cache: bool = True,
) -> CollisionModel:
    """Fit the robot's balls and list the pairs to check against each other and the scene.

    Parameters
    ----------
    robot : RobotModel
        The robot with its collision geometry.
    scene : Scene, optional
        Obstacles; none when omitted.
    self_collision : bool
        Check the robot against itself (default).
    pairs : CollisionPairs, optional
        The self-collision pairs; :func:`~.pairs.self_collision_pairs` with the
        shipped SRDF when omitted.
    tau : float
        Soft-minimum smoothing length in [m] (0: the exact, non-smooth minimum).
    cache : bool
        Read and write fits in the cache folder.

    Returns
    -------
    CollisionModel
        Balls, placed obstacles and pairs.

    Raises
    ------
    FrameNotFound
        An obstacle is carried by a frame the robot lacks.
    ParameterError
        ``tau`` is negative or not finite.
    """
    tau = check_nonnegative(tau, "tau", unit="m")
    scene = scene or Scene()
    links = _link_balls(robot, cache)
    index = {link.name: i for i, link in enumerate(links)}
    self_pairs: tuple[tuple[int, int], ...] = ()
    if self_collision:
        pairs = pairs or self_collision_pairs(robot)
        self_pairs = tuple((index[a], index[b]) for a, b in pairs.active)
    obstacles = tuple(_place(robot, o, cache) for o in scene.obstacles)
    parents = robot.model.parents
    scene_pairs = []
    for o, placed in enumerate(obstacles):
        for a, link in enumerate(links):
            if placed.joint != 0 and link.joint in (placed.joint, parents[placed.joint]):
                continue  # a carried obstacle touches the link that holds it
            if placed.joint == 0 and link.joint == 0:
                continue  # two fixed things never move relative to each other
            scene_pairs.append((a, o))
    return CollisionModel(
        robot=robot.name,
        n_joints=robot.model.njoints - 1,
        links=links,
        obstacles=obstacles,
        self_pairs=self_pairs,
        scene_pairs=tuple(scene_pairs),
        tau=tau,
        pairs=pairs,
    )
