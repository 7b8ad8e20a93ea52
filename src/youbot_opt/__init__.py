"""youbot_opt: Pinocchio-backed trajectory and IK-path optimisation with CasADi.

The public API is re-exported here; see the README for a tour. Meshcat replay
lives in :mod:`youbot_opt.viz` (imported lazily) and IK paths in
:mod:`youbot_opt.ikpath`.
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

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

if TYPE_CHECKING:  # the lazily imported names, for type checkers and IDEs
    from youbot_opt.dynamics import Dynamics, available_backends, build_dynamics
    from youbot_opt.nlp.ipopt import IpoptOptions
    from youbot_opt.nlp.status import SolveStatus
    from youbot_opt.reproduction.study1 import study1_problem
    from youbot_opt.robot.catalogue import available_robots
    from youbot_opt.robot.load import load_model
    from youbot_opt.robot.model import RobotModel, TipPose, frame_placement, tip_pose
    from youbot_opt.robot.params import (
        STUDY_Q_GOAL,
        STUDY_Q_START,
        YOUBOT_PLANAR,
        ArmParameters,
        JointLimits,
        LinkParameters,
        PlatformMounting,
    )
    from youbot_opt.robot.urdf import build_urdf, urdf_string, write_urdf
    from youbot_opt.robot.urdf_check.loader import (
        LoadedURDF,
        check_model,
        check_urdf_text,
        load_urdf_strict,
    )
    from youbot_opt.robot.urdf_check.size import SizeLimits
    from youbot_opt.sweeps.options import SweepOptions
    from youbot_opt.trajopt.bound_scaling import BoundScalingResult, bound_scaling_study
    from youbot_opt.trajopt.certify import Certificate, Tolerances, certify
    from youbot_opt.trajopt.io import load_refined, load_result, save_result
    from youbot_opt.trajopt.multistart import MultistartResult, run_multistart
    from youbot_opt.trajopt.pareto import ParetoFront, pareto_sweep
    from youbot_opt.trajopt.problem import BoundaryState, JointBounds, TrajOptProblem
    from youbot_opt.trajopt.refine import (
        Refined,
        Refinement,
        RefinementBudget,
        RefinementRound,
        refine,
    )
    from youbot_opt.trajopt.result import TrajOptResult
    from youbot_opt.trajopt.solver import TrajOptSolver
    from youbot_opt.trajopt.spline_guess import random_spline_guess
    from youbot_opt.trajopt.trajectory import Trajectory

_LAZY: dict[str, str] = {
    # models, parameters, URDF and dynamics (import Pinocchio and CasADi on first use)
    "Dynamics": "youbot_opt.dynamics",
    "available_backends": "youbot_opt.dynamics",
    "build_dynamics": "youbot_opt.dynamics",
    "LoadedURDF": "youbot_opt.robot.urdf_check.loader",
    "check_model": "youbot_opt.robot.urdf_check.loader",
    "check_urdf_text": "youbot_opt.robot.urdf_check.loader",
    "load_urdf_strict": "youbot_opt.robot.urdf_check.loader",
    "RobotModel": "youbot_opt.robot.model",
    "SizeLimits": "youbot_opt.robot.urdf_check.size",
    "TipPose": "youbot_opt.robot.model",
    "available_robots": "youbot_opt.robot.catalogue",
    "frame_placement": "youbot_opt.robot.model",
    "load_model": "youbot_opt.robot.load",
    "tip_pose": "youbot_opt.robot.model",
    "STUDY_Q_GOAL": "youbot_opt.robot.params",
    "STUDY_Q_START": "youbot_opt.robot.params",
    "YOUBOT_PLANAR": "youbot_opt.robot.params",
    "ArmParameters": "youbot_opt.robot.params",
    "JointLimits": "youbot_opt.robot.params",
    "LinkParameters": "youbot_opt.robot.params",
    "PlatformMounting": "youbot_opt.robot.params",
    "Trajectory": "youbot_opt.trajopt.trajectory",
    "build_urdf": "youbot_opt.robot.urdf",
    "urdf_string": "youbot_opt.robot.urdf",
    "write_urdf": "youbot_opt.robot.urdf",
    # trajectory optimisation: problem -> solver -> result (imports CasADi/SciPy on first use)
    "BoundaryState": "youbot_opt.trajopt.problem",
    "JointBounds": "youbot_opt.trajopt.problem",
    "TrajOptProblem": "youbot_opt.trajopt.problem",
    "study1_problem": "youbot_opt.reproduction.study1",
    "IpoptOptions": "youbot_opt.nlp.ipopt",
    "TrajOptSolver": "youbot_opt.trajopt.solver",
    "SolveStatus": "youbot_opt.nlp.status",
    "TrajOptResult": "youbot_opt.trajopt.result",
    "save_result": "youbot_opt.trajopt.io",
    "load_result": "youbot_opt.trajopt.io",
    "load_refined": "youbot_opt.trajopt.io",
    # independent checks
    "Certificate": "youbot_opt.trajopt.certify",
    "Tolerances": "youbot_opt.trajopt.certify",
    "certify": "youbot_opt.trajopt.certify",
    # adaptive mesh refinement until certified
    "Refined": "youbot_opt.trajopt.refine",
    "Refinement": "youbot_opt.trajopt.refine",
    "RefinementBudget": "youbot_opt.trajopt.refine",
    "RefinementRound": "youbot_opt.trajopt.refine",
    "refine": "youbot_opt.trajopt.refine",
    # initial guesses and studies
    "random_spline_guess": "youbot_opt.trajopt.spline_guess",
    "MultistartResult": "youbot_opt.trajopt.multistart",
    "run_multistart": "youbot_opt.trajopt.multistart",
    "ParetoFront": "youbot_opt.trajopt.pareto",
    "pareto_sweep": "youbot_opt.trajopt.pareto",
    "BoundScalingResult": "youbot_opt.trajopt.bound_scaling",
    "bound_scaling_study": "youbot_opt.trajopt.bound_scaling",
    "SweepOptions": "youbot_opt.sweeps.options",
}
"""Public names imported on first access, so ``import youbot_opt`` stays fast."""


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'youbot_opt' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


from youbot_opt._version import __version__  # noqa: E402

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
    "SizeLimits",
    "TipPose",
    "available_robots",
    "frame_placement",
    "load_model",
    "tip_pose",
    # dynamics
    "Dynamics",
    "available_backends",
    "build_dynamics",
    # trajectories and trajectory optimisation
    "Trajectory",
    "BoundaryState",
    "JointBounds",
    "TrajOptProblem",
    "study1_problem",
    "IpoptOptions",
    "TrajOptSolver",
    "SolveStatus",
    "TrajOptResult",
    "save_result",
    "load_result",
    "load_refined",
    "Certificate",
    "Tolerances",
    "certify",
    "Refined",
    "Refinement",
    "RefinementBudget",
    "RefinementRound",
    "refine",
    "random_spline_guess",
    "MultistartResult",
    "run_multistart",
    "ParetoFront",
    "pareto_sweep",
    "BoundScalingResult",
    "bound_scaling_study",
    "SweepOptions",
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
