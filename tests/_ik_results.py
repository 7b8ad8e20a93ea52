"""IK-path results that meet their targets exactly, built without a solve (for io tests)."""

from __future__ import annotations

import numpy as np

from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.result import IKPathResult, build_result
from youbot_opt.ikpath.targets import Target
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.model import RobotModel


def exact_result(robot: RobotModel) -> IKPathResult:
    """Two position targets at the tip placements of two in-limit configurations (met exactly)."""
    base = CyclicIKProblem(
        robot=robot.model,
        frame=robot.tip_frame,
        targets=(Target(position=(0, 0, 0)), Target(position=(0, 0, 0))),
    )
    q = np.random.default_rng(5).uniform(base.q_lower, base.q_upper, (2, base.n_joints)) * 0.5
    problem = base.with_targets(
        tuple(Target(position=base.placement(theta).translation) for theta in q)
    )
    return build_result(
        problem,
        method="al",
        status=SolveStatus.SOLVED,
        x=q.ravel(),
        multipliers=np.zeros(problem.n_constraints),
        iterations=2,
        wall_time=0.1,
        message="converged",
        start=q.ravel(),
    )
