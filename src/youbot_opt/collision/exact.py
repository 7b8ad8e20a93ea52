"""Exact distances with coal: the checker the certificate and the tests trust.

Each link's collision geometry is a solid: a primitive as it is, a mesh as the
convex hull of its vertices (coal's distance between convex solids is signed:
negative is penetration depth). Obstacles are coal primitives or a mesh's
convex hull. The pairs are the :class:`~youbot_opt.collision.model.CollisionModel`'s,
in its order: for separated pairs ``model.distances(q) <= exact_distances(q)``.

>>> d = exact_distances(cm, robot, q)  # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from youbot_opt._typing import Array
from youbot_opt.collision.model import CollisionModel, PlacedObstacle, joint_placements
from youbot_opt.collision.shapes import Box, Capsule, Cylinder, HalfSpace, Sphere
from youbot_opt.collision.spheres import hull_points
from youbot_opt.robot.model import RobotModel

__all__ = ["ExactChecker", "convex_hull_solid", "exact_checker", "exact_distances"]


def convex_hull_solid(points: Array) -> coal.CollisionGeometry:
    """Return the coal Convex hull of points [m] (the solid a mesh counts as)."""
    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(0, len(points))
    bvh.addVertices(np.asarray(points, dtype=float))
    bvh.endModel()
    bvh.buildConvexHull(True, "Qt")
    return bvh.convex


def _solid(geometry: Any) -> Any:
    if isinstance(geometry, coal.BVHModelBase):
        return convex_hull_solid(np.asarray(geometry.vertices(), dtype=float))
    return geometry


def _obstacle_solid(placed: PlacedObstacle) -> Any:
    shape = placed.obstacle.shape
    if isinstance(shape, Box):
        return coal.Box(*shape.size)
    if isinstance(shape, Sphere):
        return coal.Sphere(shape.radius)
    if isinstance(shape, Cylinder):
        return coal.Cylinder(shape.radius, shape.length)
    if isinstance(shape, Capsule):
        return coal.Capsule(shape.radius, shape.length)
    if isinstance(shape, HalfSpace):
        return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    return convex_hull_solid(hull_points(shape).points)


@dataclass(frozen=True, slots=True, kw_only=True)
class ExactChecker:
    """coal solids of a collision model's links and obstacles, built once.

    Attributes
    ----------
    model : CollisionModel
        The pairs and placements.
    link_solids : tuple
        A coal geometry per link geometry (meshes as convex hulls).
    link_placements : tuple of pinocchio.SE3
        Each link geometry's placement in its parent joint's frame.
    obstacle_solids : tuple
        A coal geometry per obstacle.
    """

    model: CollisionModel
    link_solids: tuple[coal.CollisionGeometry, ...]
    link_placements: tuple[pin.SE3, ...]
    obstacle_solids: tuple[coal.CollisionGeometry, ...]

    def distances(self, robot: RobotModel, q: Array) -> Array:
        """Return coal's signed distance [m] of every checked pair at ``q``.

        Parameters
        ----------
        robot : RobotModel
            The robot.
        q : ndarray, shape (nq,)
            Configuration in [rad] or [m].

        Returns
        -------
        ndarray, shape (n_pairs,)
            In the order of ``model.pair_names``; negative: penetration depth.
        """
        rotations, translations = joint_placements(robot, q)

        def joint(k: int) -> pin.SE3:
            if k == 0:
                return pin.SE3.Identity()
            return pin.SE3(rotations[:, 3 * (k - 1) : 3 * k], translations[:, k - 1])

        def tf(m: pin.SE3) -> Any:
            return coal.Transform3s(m.rotation, m.translation)

        links = [
            tf(joint(link.joint) * self.link_placements[i])
            for i, link in enumerate(self.model.links)
        ]
        obstacles = [
            tf(joint(p.joint) * pin.SE3(p.rotation, p.translation)) for p in self.model.obstacles
        ]
        request = coal.DistanceRequest()
        out = []
        for a, b in self.model.self_pairs:
            result = coal.DistanceResult()
            out.append(
                coal.distance(
                    self.link_solids[a], links[a], self.link_solids[b], links[b], request, result
                )
            )
        for a, o in self.model.scene_pairs:
            result = coal.DistanceResult()
            out.append(
                coal.distance(
                    self.link_solids[a],
                    links[a],
                    self.obstacle_solids[o],
                    obstacles[o],
                    request,
                    result,
                )
            )
        return np.array(out, dtype=float)


def exact_checker(model: CollisionModel, robot: RobotModel) -> ExactChecker:
    """Build the coal solids of a collision model.

    Parameters
    ----------
    model : CollisionModel
        From :func:`~youbot_opt.collision.model.build_collision_model`.
    robot : RobotModel
        The robot it was built for.

    Returns
    -------
    ExactChecker
        Ready to evaluate distances.
    """
    geoms = {g.name: g for g in robot.collision_model.geometryObjects}
    solids, placements = [], []
    for link in model.links:
        geom = geoms[link.name]
        solids.append(_solid(geom.geometry))
        placements.append(pin.SE3(geom.placement))
    return ExactChecker(
        model=model,
        link_solids=tuple(solids),
        link_placements=tuple(placements),
        obstacle_solids=tuple(_obstacle_solid(p) for p in model.obstacles),
    )


def exact_distances(model: CollisionModel, robot: RobotModel, q: Array) -> Array:
    """Return coal's signed distance [m] of every checked pair at ``q`` (builds the solids once).

    Parameters
    ----------
    model : CollisionModel
        The pairs.
    robot : RobotModel
        The robot.
    q : ndarray, shape (nq,)
        Configuration in [rad] or [m].

    Returns
    -------
    ndarray, shape (n_pairs,)
        Distances in [m].
    """
    return exact_checker(model, robot).distances(robot, q)
