"""Fixtures shared by the IK-path tests."""

from __future__ import annotations

import numpy as np
import pytest

from youbot_opt.ikpath.problem import CyclicIKProblem
from youbot_opt.ikpath.targets import Target
from youbot_opt.robot.load import load_model


@pytest.fixture(scope="module")
def ur5_reachable() -> CyclicIKProblem:
    """UR5 through 3 positions that are placements of random angles (so reachable)."""
    robot = load_model("ur5")
    base = CyclicIKProblem(
        robot=robot.model,
        frame=robot.tip_frame,
        targets=(Target(position=(0, 0, 0)), Target(position=(0, 0, 0))),
    )
    rng = np.random.default_rng(0)
    return base.with_targets(
        tuple(Target(position=base.placement(rng.uniform(-2, 2, 6)).translation) for _ in range(3))
    )
