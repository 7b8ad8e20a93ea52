"""Clearance as NLP constraints (#28 items 4 and 7): the youBot swings around a ball.

Known answer: the study youBot's free optimum passes straight up through a ball
placed just above its tip at mid-motion; with the ball in the scene every
transcription keeps coal's exact clearance >= the margin at its knots and, by the
certificate, between them, at an objective no lower than its own free optimum.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from youbot_opt.collision import Obstacle, Scene, Sphere
from youbot_opt.collision.clearance import Clearance, clearance_checker
from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.study1 import STUDY_Q_GOAL, STUDY_Q_START
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import frame_placement
from youbot_opt.trajopt.clearance import certify_plan_clearance, clearance_constraint
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.solver import TrajOptSolver

MARGIN = 0.01  # [m]
# The exact distance may fall below the NLP's margin only by the soft-min and
# ball-model slack at points the NLP does not constrain; the NLP's model distance
# is never above coal's, so at the constrained points coal reads >= margin minus
# IPOPT's feasibility tolerance (1e-6 m scale): 1e-5 m.
KNOT_TOL = 1e-5  # [m]


@pytest.fixture(autouse=True)
def _fit_cache(fit_cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Sphere fits are cached in a temporary folder during each test, never the user's."""
    monkeypatch.setenv("YOUBOT_OPT_CACHE", str(fit_cache))


@pytest.fixture(scope="module")
def free() -> TrajOptProblem:
    """The study's swing from -30/-30/-60 to 30/30/60 degrees on 20 knots, no scene."""
    return TrajOptProblem(
        robot=load_model("youbot"),
        start=BoundaryState(q=np.array(STUDY_Q_START)),
        goal=BoundaryState(q=np.array(STUDY_Q_GOAL)),
        n_knots=20,
    )


def _ball_over_tip(problem: TrajOptProblem) -> Clearance:
    """A 3 cm ball 2 cm above the tip of the arm standing straight up (q = 0, mid-motion)."""
    tip = frame_placement(problem.robot, np.zeros(problem.nv), "gripper_tip").translation
    ball = Obstacle(name="ball", shape=Sphere(radius=0.03), xyz=tuple(tip + [0.0, 0.0, 0.02]))
    return Clearance(scene=Scene((ball,)), margin=MARGIN, self_collision=False)


def test_scene_less_nlp_unchanged(free: TrajOptProblem) -> None:
    """No clearance: no path-constraint block, the same rows as a problem without the field."""
    for method in ("trapezoidal", "hermite_simpson", "radau"):
        nlp = TrajOptSolver(free, method).nlp
        assert not nlp.path_limits
        assert not any(name.startswith("clearance") for name in nlp.constraints.blocks)
    assert clearance_constraint(free) is None


@pytest.mark.parametrize("method", ["trapezoidal", "hermite_simpson", "radau"])
def test_swing_around_ball(free: TrajOptProblem, method: str) -> None:
    """The free optimum clips the ball; the constrained one keeps the margin, costs more."""
    clearance = _ball_over_tip(free)
    problem = dataclasses.replace(free, clearance=clearance)
    checker = clearance_checker(problem.robot, clearance)
    unconstrained = TrajOptSolver(free, method).solve(beta=0.5)
    assert unconstrained.status.success and unconstrained.trajectory is not None
    times = np.linspace(0.0, unconstrained.duration, 201)
    clip = min(checker.distances(problem.robot, unconstrained.trajectory(t)).min() for t in times)
    assert clip < 0.0  # the free optimum passes through the ball

    solver = TrajOptSolver(problem, method)
    n_points = problem.n_knots + (problem.n_knots - 1) * (2 if method == "radau" else 1)
    constraint = clearance_constraint(problem)
    assert constraint is not None and constraint.width == 3  # three arm links, one ball
    rows = constraint.width * n_points
    assert solver.nlp.n_constraints == TrajOptSolver(free, method).nlp.n_constraints + rows
    assert sum(solver.nlp.constraints[name].size for name in solver.nlp.path_limits) == rows
    result = solver.solve(beta=0.5)
    assert result.status.success and result.trajectory is not None
    knots = [checker.distances(problem.robot, q).min() for q in result.trajectory.q]
    assert min(knots) >= MARGIN - KNOT_TOL
    cert = certify_plan_clearance(result.trajectory, problem.robot, checker, margin=MARGIN)
    assert cert.certified, cert
    # the free optimum is feasible for no fewer constraints: a relaxation
    assert result.objective >= unconstrained.objective - 1e-9 * abs(unconstrained.objective)


def test_start_inside_obstacle_refused(free: TrajOptProblem) -> None:
    """A ball around the start's tip refuses the solver before any solve, naming the start."""
    tip = frame_placement(free.robot, free.start.q, "gripper_tip").translation
    ball = Obstacle(name="ball", shape=Sphere(radius=0.05), xyz=tuple(tip))
    problem = dataclasses.replace(
        free, clearance=Clearance(scene=Scene((ball,)), self_collision=False)
    )
    with pytest.raises(ParameterError, match=r"start: link geometry '\w+' penetrates obstacle"):
        TrajOptSolver(problem)


def test_clearance_margin_checked() -> None:
    """A negative margin is refused, naming it."""
    with pytest.raises(ParameterError, match="margin"):
        Clearance(margin=-0.01)


def test_saved_clearance_rechecked_on_load(free: TrajOptProblem, tmp_path) -> None:
    """The scene and margin round-trip; a loaded plan is checked against coal, not the file."""
    from youbot_opt.trajopt.io import load_result, save_result

    problem = dataclasses.replace(free, clearance=_ball_over_tip(free))
    result = TrajOptSolver(problem).solve(beta=0.5)
    assert result.status.success
    assert result.check().clearance >= MARGIN - result.feasibility_tol
    loaded = load_result(save_result(result, tmp_path / "swing"))
    assert loaded.problem.clearance == problem.clearance
    assert loaded.status.success
    # the same plan under a larger margin than it keeps: the check refuses it on load
    wider = dataclasses.replace(problem.clearance, margin=0.05)
    strict = dataclasses.replace(result, problem=dataclasses.replace(problem, clearance=wider))
    reloaded = load_result(save_result(strict, tmp_path / "strict"))
    assert not reloaded.status.success
    assert "clearance" in reloaded.message and "'ball'" in reloaded.message


def test_refinement_removes_a_clip_between_knots(free: TrajOptProblem) -> None:
    """A 5 mm ball on the free tip path between the constrained points of a 4-knot grid.

    The knots-and-midpoints NLP does not see it (its plan is the free one) and
    the exact certificate finds the clip; refinement splits that interval and
    ends with a plan whose clearance the certificate proves at every time.
    """
    from youbot_opt.trajopt.refine import RefinementBudget, refine

    coarse = dataclasses.replace(free, n_knots=4)
    plan = TrajOptSolver(coarse).solve(beta=0.5)
    assert plan.trajectory is not None
    when = 1.3 * plan.duration / 3  # 30 % into interval 1, between knot 1 and its midpoint
    tip = frame_placement(coarse.robot, plan.trajectory(when), "gripper_tip").translation
    ball = Obstacle(name="ball", shape=Sphere(radius=0.005), xyz=tuple(tip))
    clearance = Clearance(scene=Scene((ball,)), self_collision=False)
    problem = dataclasses.replace(coarse, clearance=clearance)
    checker = clearance_checker(problem.robot, clearance)
    solver = TrajOptSolver(problem)
    knots_only = solver.solve(beta=0.5)
    assert knots_only.status.success and knots_only.trajectory is not None
    assert not certify_plan_clearance(knots_only.trajectory, problem.robot, checker).certified

    refined = refine(solver, beta=0.5, budget=RefinementBudget(certify=False))
    first = refined.refinement.rounds[0]
    assert first.certificate_passed is False
    assert any("clearance" in f and "'ball'" in f for f in first.failures)
    assert refined.refinement.certified, refined.refinement.reason
    assert refined.result.trajectory is not None
    cert = certify_plan_clearance(refined.result.trajectory, problem.robot, checker)
    assert cert.certified and cert.lower_bound >= -cert.tolerance
    # from a plan solved beforehand (the command line's way): the rounds' solvers check
    # the plan's own ends with coal too (a finer grid's solver shares the coal checker)
    again = refine(solver, first=knots_only, budget=RefinementBudget(certify=False))
    assert again.refinement.certified, again.refinement.reason
    assert [r.n_knots for r in again.refinement.rounds] == [
        r.n_knots for r in refined.refinement.rounds
    ]


def test_ball_overshoot_at_the_start_refused(free: TrajOptProblem) -> None:
    """Self-collision on the youBot: a margin the balls cannot meet at the start is refused.

    Coal clears ('arm_link_1_0', 'arm_link_3_0') at the study's start by 94.7 mm,
    their balls by 91.0 mm: with a 93 mm margin the NLP would be infeasible at
    its fixed first knot, so the solver refuses it first, naming the pair and
    both distances.
    A 1 cm margin, refused by the slab fit of before (6 mm there), is accepted.
    """
    TrajOptSolver(dataclasses.replace(free, clearance=Clearance(margin=MARGIN)))
    problem = dataclasses.replace(free, clearance=Clearance(margin=0.093))
    with pytest.raises(ParameterError, match=r"start: the bounding balls of pair 'arm_link_1_0"):
        TrajOptSolver(problem)


def test_ball_overshoot_at_an_overridden_start_refused(free: TrajOptProblem) -> None:
    """A start given to ``solve()`` is held to the NLP's ball margin as a built one is.

    The study's start to itself with the elbow opened by 0.2 rad, a 90 mm
    self-collision margin: both ends clear it by coal and by the balls, so the
    solver builds. The start then turned by -0.3 rad at the first joint keeps
    coal's 94.7 mm but brings a pair's balls to 87.2 mm: the NLP would be
    infeasible at its fixed first knot, so ``solve(start=...)`` refuses it
    before IPOPT runs, naming the pair and both distances (before, only coal
    was asked and IPOPT ran an infeasible NLP: issue 28's ur5 shelf pairs).
    """
    goal = np.array(STUDY_Q_START, dtype=float)
    goal[2] += 0.2
    problem = dataclasses.replace(
        free, goal=BoundaryState(q=goal), clearance=Clearance(margin=0.09)
    )
    solver = TrajOptSolver(problem)
    start = np.array(STUDY_Q_START, dtype=float)
    start[0] -= 0.3
    rows = clearance_constraint(problem)
    assert rows is not None
    balls = np.asarray(rows.function(start, np.zeros(3)), dtype=float).ravel()
    checker = clearance_checker(problem.robot, problem.clearance)
    assert balls.min() < 0.09 <= checker.distances(problem.robot, start).min()  # the premise
    with pytest.raises(ParameterError, match=r"start: the bounding balls of pair .* \(coal: "):
        solver.solve(beta=0.5, start=start)
