"""Exact clearance: configurations refused naming link and obstacle; motions certified."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from youbot_opt.collision import (
    Box,
    Cylinder,
    Obstacle,
    Scene,
    build_collision_model,
    certify_clearance,
    exact_checker,
    point_speed_bounds,
    require_clearance,
)
from youbot_opt.collision.model import joint_placements
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import RobotModel


@pytest.fixture(scope="module")
def pillar_checker(ur5: RobotModel, fit_cache: Path):
    """ur5 with a thin pillar at 0.45 m on the y axis, no self-collision."""
    pillar = Obstacle(name="pillar", shape=Cylinder(radius=0.02, length=2.0), xyz=(0.0, 0.45, 0.5))
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))
        cm = build_collision_model(ur5, Scene((pillar,)), self_collision=False)
    return exact_checker(cm, ur5)


def test_start_inside_obstacle_refused_naming_link_and_obstacle(ur5: RobotModel):
    """A box around the base refuses q = 0, naming the shoulder's geometry and the box."""
    crate = Obstacle(name="crate", shape=Box(size=(0.3, 0.3, 0.3)), xyz=(0.0, 0.0, 0.1))
    checker = exact_checker(build_collision_model(ur5, Scene((crate,))), ur5)
    with pytest.raises(
        ParameterError, match=r"start: link geometry 'shoulder_link_0' penetrates obstacle 'crate'"
    ):
        require_clearance(checker, ur5, np.zeros(ur5.nq), what="start")


def test_margin_refuses_a_near_configuration(ur5: RobotModel, pillar_checker):
    """q = 0 clears the pillar at margin 0 and fails at a margin of 1 m."""
    q = np.zeros(ur5.nq)
    require_clearance(pillar_checker, ur5, q, what="goal")
    with pytest.raises(
        ParameterError, match="goal: .* is closer than the margin to obstacle 'pillar'"
    ):
        require_clearance(pillar_checker, ur5, q, margin=1.0, what="goal")


def test_speed_bound_holds(ur5: RobotModel, pillar_checker, rng):
    """Every ball centre of every link moves slower than its pair's bound at 20 random (q, v)."""
    cm = pillar_checker.model
    v_max = ur5.velocity_limit
    bound = point_speed_bounds(pillar_checker, ur5, v_max)
    h = 1e-7  # [s]
    for _ in range(20):
        q = rng.uniform(-np.pi, np.pi, ur5.nq)
        v = rng.uniform(-1, 1, ur5.nq) * v_max
        r0, p0 = joint_placements(ur5, q)
        r1, p1 = joint_placements(ur5, q + h * v)
        for k, (a, _) in enumerate(cm.scene_pairs):
            link = cm.links[a]
            if link.joint == 0:
                continue
            j = link.joint - 1
            x0 = link.centers @ r0[:, 3 * j : 3 * j + 3].T + p0[:, j]
            x1 = link.centers @ r1[:, 3 * j : 3 * j + 3].T + p1[:, j]
            speed = np.linalg.norm(x1 - x0, axis=1).max() / h
            assert speed <= bound[k] * (1 + 1e-6), (link.name, speed, bound[k])


def test_certificate_finds_a_clip_between_samples(ur5: RobotModel, pillar_checker):
    """Swinging through the pillar between two clear samples is not certified: the clip is found."""
    q0 = np.zeros(ur5.nq)
    q0[1] = -np.pi / 2  # the arm stands up, the forearm reaches along x
    q0[2] = np.pi / 2

    def motion(t: float) -> np.ndarray:  # the shoulder turns from -60 to 240 degrees in 2 s
        q = q0.copy()
        q[0] = np.deg2rad(-60 + 150 * t)
        return q

    ends = [pillar_checker.distances(ur5, motion(t)).min() for t in (0.0, 2.0)]
    assert min(ends) > 0.05  # the two samples alone look clear
    cert = certify_clearance(
        pillar_checker, ur5, motion, np.array([0.0, 2.0]), v_max=ur5.velocity_limit
    )
    assert not cert.certified and cert.failures
    assert cert.closest_pair[1] == "pillar" and cert.closest_distance < 0


def test_certificate_of_a_clear_motion(ur5: RobotModel, pillar_checker):
    """A small motion away from the pillar is certified with a positive lower bound."""
    q0 = np.zeros(ur5.nq)

    def motion(t: float) -> np.ndarray:
        q = q0.copy()
        q[0] = -np.pi / 2 + 0.2 * t  # turning away from +y
        return q

    cert = certify_clearance(
        pillar_checker,
        ur5,
        motion,
        np.linspace(0.0, 1.0, 5),
        v_max=np.full(ur5.nq, 0.25),
        margin=0.01,
    )
    assert cert.certified and cert.lower_bound >= 0.01 - cert.tolerance
    assert cert.n_samples >= 5 and cert.speed_bound > 0
