"""Collision (layer L2): scenes of obstacles, self-collision pairs, bounding balls, distances.

Modules: :mod:`.shapes` and :mod:`.scene` (:class:`Scene`, furniture URDFs),
:mod:`.scene_file` (the JSON file), :mod:`.pairs` (self-collision, SRDF),
:mod:`.spheres` (bounding balls, cached, with their overshoot),
:mod:`.distance` (smooth CasADi distances), :mod:`.model`
(:class:`CollisionModel`: the distances as a Function of the joints'
placements), :mod:`.exact` (coal's exact distances) and :mod:`.clearance`
(:class:`Clearance`, the spec both optimisers take; configurations refused
before solving, motions certified between samples).

    from youbot_opt.collision import Scene, build_collision_model
"""

from youbot_opt.collision.clearance import (
    Clearance,
    ClearanceCertificate,
    certify_clearance,
    clearance_checker,
    collision_model,
    point_speed_bounds,
    require_clearance,
)
from youbot_opt.collision.exact import ExactChecker, exact_checker, exact_distances
from youbot_opt.collision.model import CollisionModel, build_collision_model, joint_placements
from youbot_opt.collision.pairs import CollisionPairs, pairs_report, self_collision_pairs
from youbot_opt.collision.scene import Obstacle, Scene, furniture
from youbot_opt.collision.scene_file import load_scene, save_scene
from youbot_opt.collision.shapes import Box, Capsule, Cylinder, HalfSpace, Mesh, Sphere

__all__ = [
    "Box",
    "Capsule",
    "Clearance",
    "ClearanceCertificate",
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
    "certify_clearance",
    "clearance_checker",
    "collision_model",
    "exact_checker",
    "exact_distances",
    "furniture",
    "joint_placements",
    "load_scene",
    "pairs_report",
    "point_speed_bounds",
    "require_clearance",
    "save_scene",
    "self_collision_pairs",
]
