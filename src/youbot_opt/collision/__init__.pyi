"""Public names of :mod:`youbot_opt.collision`, listed once (read by ``lazy_loader``)."""

from .clearance import (
    Clearance as Clearance,
    ClearanceCertificate as ClearanceCertificate,
    certify_clearance as certify_clearance,
    clearance_checker as clearance_checker,
    clearance_document as clearance_document,
    clearance_from_document as clearance_from_document,
    collision_model as collision_model,
    point_speed_bounds as point_speed_bounds,
    require_clearance as require_clearance,
)
from .exact import (
    ExactChecker as ExactChecker,
    exact_checker as exact_checker,
    exact_distances as exact_distances,
)
from .model import (
    CollisionModel as CollisionModel,
    build_collision_model as build_collision_model,
    joint_placements as joint_placements,
)
from .pairs import (
    CollisionPairs as CollisionPairs,
    pairs_report as pairs_report,
    self_collision_pairs as self_collision_pairs,
)
from .scene import Obstacle as Obstacle, Scene as Scene, furniture as furniture
from .scene_file import load_scene as load_scene, save_scene as save_scene
from .shapes import (
    Box as Box,
    Capsule as Capsule,
    Cylinder as Cylinder,
    HalfSpace as HalfSpace,
    Mesh as Mesh,
    Sphere as Sphere,
)
