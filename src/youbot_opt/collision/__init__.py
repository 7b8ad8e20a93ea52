"""Collision (layer L2): scenes of obstacles, self-collision pairs, bounding balls, distances.

Modules: :mod:`.shapes` (box, sphere, cylinder, capsule, half-space, mesh),
:mod:`.scene` (:class:`Scene`, :class:`Obstacle`, furniture from a URDF),
:mod:`.scene_file` (the JSON scene file), :mod:`.pairs` (self-collision pairs,
SRDF), :mod:`.spheres` (bounding balls fitted once, cached, with their
overshoot), :mod:`.distance` (smooth signed distances in CasADi),
:mod:`.model` (:class:`CollisionModel`: the CasADi distances of a robot in a
scene as a Function of the joints' placements) and :mod:`.exact` (coal's exact
distances, the independent checker).

    from youbot_opt.collision import Scene, build_collision_model
"""

from youbot_opt.collision.exact import ExactChecker, exact_checker, exact_distances
from youbot_opt.collision.model import CollisionModel, build_collision_model, joint_placements
from youbot_opt.collision.pairs import CollisionPairs, pairs_report, self_collision_pairs
from youbot_opt.collision.scene import Obstacle, Scene, furniture
from youbot_opt.collision.scene_file import load_scene, save_scene
from youbot_opt.collision.shapes import Box, Capsule, Cylinder, HalfSpace, Mesh, Sphere

__all__ = [
    "Box",
    "Capsule",
    "CollisionModel",
    "CollisionPairs",
    "Cylinder",
    "ExactChecker",
    "HalfSpace",
    "Mesh",
    "Obstacle",
    "Scene",
    "Sphere",
    "build_collision_model",
    "exact_checker",
    "exact_distances",
    "furniture",
    "joint_placements",
    "load_scene",
    "pairs_report",
    "save_scene",
    "self_collision_pairs",
]
