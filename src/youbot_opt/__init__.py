"""youbot_opt: Pinocchio-backed trajectory and IK-path optimisation with CasADi.

The public API is re-exported here; see the README for a tour. Meshcat replay
lives in :mod:`youbot_opt.viz` (imported lazily) and IK paths in
:mod:`youbot_opt.ikpath`.
"""

from __future__ import annotations

import logging

from youbot_opt.dynamics import Dynamics, available_backends, build_dynamics
from youbot_opt.exceptions import (
    FrameNotFound,
    InvalidModelError,
    ModelError,
    ParameterError,
    ResourceNotFoundError,
    ResultFileError,
    RobotNotFound,
    SolveFailed,
    TranscriptionError,
    UnreachableTarget,
    UnsafePathError,
    UnsafeURDFError,
    URDFError,
    URDFStructureError,
    URDFSyntaxError,
    ViewerError,
    YoubotOptError,
    YoubotOptWarning,
)
from youbot_opt.loader import LoadedURDF, check_model, check_urdf_text, load_urdf_strict
from youbot_opt.model import (
    RobotModel,
    TipPose,
    available_robots,
    frame_placement,
    load_model,
    tip_pose,
)
from youbot_opt.params import (
    STUDY_Q_GOAL,
    STUDY_Q_START,
    YOUBOT_PLANAR,
    ArmParameters,
    JointLimits,
    LinkParameters,
    PlatformMounting,
)
from youbot_opt.trajectory import Trajectory
from youbot_opt.urdf import build_urdf, urdf_string, write_urdf

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = [
    "__version__",
    # parameters, URDF, models
    "ArmParameters",
    "JointLimits",
    "LinkParameters",
    "PlatformMounting",
    "STUDY_Q_GOAL",
    "STUDY_Q_START",
    "YOUBOT_PLANAR",
    "build_urdf",
    "urdf_string",
    "write_urdf",
    "LoadedURDF",
    "check_model",
    "check_urdf_text",
    "load_urdf_strict",
    "RobotModel",
    "TipPose",
    "available_robots",
    "frame_placement",
    "load_model",
    "tip_pose",
    # dynamics
    "Dynamics",
    "available_backends",
    "build_dynamics",
    # trajectories
    "Trajectory",
    # errors
    "FrameNotFound",
    "InvalidModelError",
    "ModelError",
    "ParameterError",
    "ResourceNotFoundError",
    "ResultFileError",
    "RobotNotFound",
    "SolveFailed",
    "TranscriptionError",
    "UnreachableTarget",
    "UnsafePathError",
    "UnsafeURDFError",
    "URDFError",
    "URDFStructureError",
    "URDFSyntaxError",
    "ViewerError",
    "YoubotOptError",
    "YoubotOptWarning",
]
