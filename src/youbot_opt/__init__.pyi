"""The public face of youbot_opt: each public name listed once, here.

``__init__.py`` reads this stub with ``lazy_loader.attach_stub``: a name is
imported from its module on first access (``import youbot_opt`` stays fast);
type checkers read the same lines.
"""

from ._version import __version__ as __version__
from .dynamics import (
    Dynamics as Dynamics,
    available_backends as available_backends,
    build_dynamics as build_dynamics,
)
from .exceptions import (
    FrameNotFound as FrameNotFound,
    InvalidModelError as InvalidModelError,
    ModelError as ModelError,
    ParameterError as ParameterError,
    ResourceNotFoundError as ResourceNotFoundError,
    ResultFileError as ResultFileError,
    RobotNotFound as RobotNotFound,
    SolveFailed as SolveFailed,
    TranscriptionError as TranscriptionError,
    UnreachableTarget as UnreachableTarget,
    UnsafePathError as UnsafePathError,
    UnsafeURDFError as UnsafeURDFError,
    URDFError as URDFError,
    URDFStructureError as URDFStructureError,
    URDFSyntaxError as URDFSyntaxError,
    ViewerError as ViewerError,
    YoubotOptError as YoubotOptError,
    YoubotOptWarning as YoubotOptWarning,
)
from .nlp.ipopt import IpoptOptions as IpoptOptions
from .nlp.status import SolveStatus as SolveStatus
from .reproduction.study1 import study1_problem as study1_problem
from .robot.catalogue import available_robots as available_robots
from .robot.load import load_model as load_model
from .robot.model import (
    RobotModel as RobotModel,
    TipPose as TipPose,
    frame_placement as frame_placement,
    tip_pose as tip_pose,
)
from .robot.params import (
    STUDY_Q_GOAL as STUDY_Q_GOAL,
    STUDY_Q_START as STUDY_Q_START,
    YOUBOT_PLANAR as YOUBOT_PLANAR,
    ArmParameters as ArmParameters,
    JointLimits as JointLimits,
    LinkParameters as LinkParameters,
    PlatformMounting as PlatformMounting,
)
from .robot.payload import Payload as Payload
from .robot.urdf import (
    build_urdf as build_urdf,
    urdf_string as urdf_string,
    write_urdf as write_urdf,
)
from .robot.urdf_check.loader import (
    LoadedURDF as LoadedURDF,
    check_model as check_model,
    check_urdf_text as check_urdf_text,
    load_urdf_strict as load_urdf_strict,
)
from .robot.urdf_check.size import SizeLimits as SizeLimits
from .sweeps.options import SweepOptions as SweepOptions
from .trajopt.bound_scaling import (
    BoundScalingResult as BoundScalingResult,
    bound_scaling_study as bound_scaling_study,
)
from .trajopt.certify import (
    Certificate as Certificate,
    Tolerances as Tolerances,
    certify as certify,
)
from .trajopt.export.samples import SampledTrajectory as SampledTrajectory
from .trajopt.io import (
    load_refined as load_refined,
    load_result as load_result,
    save_result as save_result,
)
from .trajopt.multistart import (
    MultistartResult as MultistartResult,
    run_multistart as run_multistart,
)
from .trajopt.pareto import ParetoFront as ParetoFront, pareto_sweep as pareto_sweep
from .trajopt.payload_sweep import payload_sweep as payload_sweep
from .trajopt.problem import (
    BoundaryState as BoundaryState,
    JointBounds as JointBounds,
    TrajOptProblem as TrajOptProblem,
)
from .trajopt.refine import (
    Refined as Refined,
    Refinement as Refinement,
    RefinementBudget as RefinementBudget,
    RefinementRound as RefinementRound,
    refine as refine,
)
from .trajopt.result import TrajOptResult as TrajOptResult
from .trajopt.solver import TrajOptSolver as TrajOptSolver
from .trajopt.spline_guess import random_spline_guess as random_spline_guess
from .trajopt.tool import (
    KeepAxis as KeepAxis,
    NearLine as NearLine,
    ToolConstraint as ToolConstraint,
    ToolSpeed as ToolSpeed,
)
from .trajopt.tool_certificate import (
    ToolCertificate as ToolCertificate,
    certify_plan_tool as certify_plan_tool,
)
from .trajopt.trajectory import Trajectory as Trajectory
from .trajopt.waypoints import Waypoints as Waypoints, load_waypoints as load_waypoints
