"""Minimum-motion cyclic IK paths: planar arms (study 2, spec ``ikpath.md``) and any robot.

One problem, :class:`CyclicIKProblem`, on a RobotModel or a PlanarChain; build,
check, solve, inspect (a 3-D robot too: :func:`solve`, :func:`run_multistart`)::

    chain = PlanarChain(lengths=[3, 2, 2], q_lower=-1.5708, q_upper=1.5708)
    problem = CyclicIKProblem(robot=chain, targets=[(-1, 5), (-3, 3), (-3, -4), (0, 5), (3, 2)])
    verdicts = check_reachability(problem)          # exact, no sampling
    result = solve(problem, method="al")            # or "ipopt"
    best = run_multistart(problem, n_starts=200, seed=0).best
"""

from __future__ import annotations

from youbot_opt.ikpath.clearance import IKClearance, certify_path_clearance
from youbot_opt.ikpath.dls import greedy_path
from youbot_opt.ikpath.examples import EXAMPLES, STUDY_E_A, example_problem
from youbot_opt.ikpath.io import load_result, save_result
from youbot_opt.ikpath.methods.al import ALOptions, solve_augmented_lagrangian
from youbot_opt.ikpath.methods.bfgs import BFGSResult, minimize_bfgs, strong_wolfe_line_search
from youbot_opt.ikpath.methods.ipopt import IpoptIKSolver, solve_ipopt
from youbot_opt.ikpath.multistart import (
    IKPathOptimum,
    MultistartResult,
    cluster_minima,
    configuration_distance,
    make_starts,
    run_multistart,
)
from youbot_opt.ikpath.problem import CyclicIKProblem, Evaluation
from youbot_opt.ikpath.reachability import Reachability
from youbot_opt.ikpath.reachability.general import ReachVerdict3D, check_reachability_3d
from youbot_opt.ikpath.reachability.planar import (
    ReachVerdict,
    check_reachability,
    decide_reachability,
    require_reachable,
)
from youbot_opt.ikpath.result import (
    IKPathResult,
    JointPath,
    OuterIterate,
)
from youbot_opt.ikpath.solve import METHODS, Method, solve
from youbot_opt.ikpath.starts import make_starts_3d
from youbot_opt.ikpath.stored import StartSummary, StoredResults
from youbot_opt.ikpath.targets import Target, load_targets
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.planar import PlanarChain, TipKinematics, chain_from_robot, youbot_chain
from youbot_opt.robot.source import RobotSource
from youbot_opt.sweeps.multistart import LocalOptimum

__all__ = [
    "ALOptions",
    "BFGSResult",
    "CyclicIKProblem",
    "EXAMPLES",
    "Evaluation",
    "IKClearance",
    "IKPathOptimum",
    "IKPathResult",
    "IpoptIKSolver",
    "IpoptOptions",
    "JointPath",
    "LocalOptimum",
    "METHODS",
    "Method",
    "MultistartResult",
    "OuterIterate",
    "PlanarChain",
    "ReachVerdict",
    "Reachability",
    "RobotSource",
    "STUDY_E_A",
    "Target",
    "ReachVerdict3D",
    "SolveStatus",
    "StartSummary",
    "StoredResults",
    "TipKinematics",
    "chain_from_robot",
    "certify_path_clearance",
    "check_reachability",
    "check_reachability_3d",
    "cluster_minima",
    "configuration_distance",
    "decide_reachability",
    "example_problem",
    "greedy_path",
    "load_targets",
    "load_result",
    "make_starts",
    "make_starts_3d",
    "minimize_bfgs",
    "require_reachable",
    "run_multistart",
    "save_result",
    "solve",
    "solve_augmented_lagrangian",
    "solve_ipopt",
    "strong_wolfe_line_search",
    "youbot_chain",
]
