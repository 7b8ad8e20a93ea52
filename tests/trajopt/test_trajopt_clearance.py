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
    """Without an end window, a margin the balls cannot meet at the start is refused.

    Coal clears ('arm_link_1_0', 'arm_link_3_0') at the study's start by 94.7 mm,
    their balls by 91.0 mm: with a 93 mm margin the NLP would be infeasible at
    its fixed first knot, so the solver refuses it first, naming the pair and
    both distances.
    A 1 cm margin, refused by the slab fit of before (6 mm there), is accepted.
    """
    TrajOptSolver(dataclasses.replace(free, clearance=Clearance(margin=MARGIN)))
    problem = dataclasses.replace(free, clearance=Clearance(margin=0.093, end_window=0.0))
    with pytest.raises(ParameterError, match=r"start: the bounding balls of pair 'arm_link_1_0"):
        TrajOptSolver(problem)


def test_ball_overshoot_at_an_overridden_start_refused(free: TrajOptProblem) -> None:
    """Without an end window a start given to ``solve()`` is held to the ball margin.

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
        free, goal=BoundaryState(q=goal), clearance=Clearance(margin=0.09, end_window=0.0)
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


def test_end_window_ramps_the_rows_from_the_ends(free: TrajOptProblem) -> None:
    """With the default end window the 93 mm margin the balls miss at both ends is solved.

    Coal keeps 93 mm at the study's start and goal, but the balls of one pair
    are 91.0 mm apart at both ends and those of another 71.0 mm at the goal
    (without the window: refused, above). The
    NLP's lower bounds of such a pair are the straight ramp from its ball
    distance at the end (s = 0, or 1) to 93 mm at s = 0.1 (or 0.9), 93 mm
    elsewhere, computed here row by row from the rows' function at the ends and
    the knot and midpoint times ``k / 19`` and ``(k + 1/2) / 19``. The plan is
    then judged by coal as any: its certificate proves the margin (less its
    1 mm tolerance) at every time, the ramped stretches included.
    """
    margin = 0.093
    clearance = Clearance(margin=margin)
    assert clearance.end_window == 0.1
    problem = dataclasses.replace(free, clearance=clearance)
    solver = TrajOptSolver(problem, "hermite_simpson")
    rows = clearance_constraint(problem)
    assert rows is not None and rows.end_window == 0.1
    ends = [
        np.asarray(rows.function(state.q, np.zeros(3)), dtype=float).ravel()
        for state in (problem.start, problem.goal)
    ]
    assert (ends[0] < margin).sum() == 1 and (ends[1] < margin).sum() == 2  # the premise
    lbg = solver.nlp.constraints.unpack(solver.nlp_bounds()[2])
    for block, s in (
        ("clearance_knots", np.arange(20) / 19),
        ("clearance_midpoints", (np.arange(19) + 0.5) / 19),
    ):
        expected = np.full((s.size, rows.width), margin)
        for end, share in zip(ends, (s, 1.0 - s), strict=True):
            for i in np.flatnonzero(end < margin):
                ramp = end[i] + (margin - end[i]) * np.minimum(share / 0.1, 1.0)
                expected[:, i] = np.minimum(expected[:, i], ramp)
        np.testing.assert_allclose(lbg[block], expected, rtol=0, atol=1e-15)
        assert np.all(lbg[block][(s >= 0.1) & (s <= 0.9)] == margin)
    result = solver.solve(beta=0.5)
    assert result.status.success and result.trajectory is not None
    checker = clearance_checker(problem.robot, clearance)
    cert = certify_plan_clearance(result.trajectory, problem.robot, checker, margin=margin)
    assert cert.certified, cert


@pytest.mark.parametrize("method", ["trapezoidal", "hermite_simpson", "radau"])
def test_point_times_are_where_the_points_lie(free: TrajOptProblem, method: str) -> None:
    """``point_times`` on a non-uniform grid: each path point's state is the plan's there.

    Independent of the times' formula: the solved plan's own interpolant
    (:class:`Trajectory`, the method's polynomial) evaluated at ``T s`` equals
    the NLP's point values (Hermite-Simpson's midpoint and Radau's stage
    variables; the trapezoid's midpoint expression
    ``(q_k + q_{k+1}) / 2 + h_k (v_k - v_{k+1}) / 8``) to the solver's rounding.
    """
    coarse = dataclasses.replace(free, n_knots=8)
    fractions = np.array([1.0, 2.0, 1.0, 3.0, 1.0, 1.0, 2.0])
    solver = TrajOptSolver(coarse, method).on_grid(fractions)
    result = solver.solve(beta=0.5)
    assert result.status.success and result.trajectory is not None
    times = solver.method.point_times(8)
    assert set(times) == {"knots", *solver.method.interior_points}
    total = result.duration
    q = result.variables["q"]
    np.testing.assert_allclose(result.trajectory(total * times["knots"]), q, atol=1e-12)
    if method == "trapezoidal":
        v, h = result.variables["v"], total * fractions / fractions.sum()
        mid = 0.5 * (q[:-1] + q[1:]) + h[:, None] * (v[:-1] - v[1:]) / 8
        groups = {"midpoints": mid}
    else:
        names = {"midpoints": "q_mid", "stage1": "q_stage1", "stage2": "q_stage2"}
        groups = {g: result.variables[names[g]] for g in times if g != "knots"}
    for group, values in groups.items():
        np.testing.assert_allclose(result.trajectory(total * times[group]), values, atol=1e-9)


def test_cached_path_kernels_load_without_being_derived(
    free: TrajOptProblem, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A second solver of one scene loads its clearance rows' compiled kernels underived.

    As the dynamics' kernels (tests/trajopt/test_solve.py): ``path_kernels`` made
    to fail, the second build still finds the rows' kernels by the rows' Function,
    and the solve reaches the first's optimum (the same compiled code: 1e-12).
    """
    from youbot_opt.nlp.codegen import find_compiler
    from youbot_opt.trajopt import solver as solver_module

    if find_compiler() is None:
        pytest.skip("no C compiler")
    problem = dataclasses.replace(free, n_knots=8, clearance=_ball_over_tip(free))
    first = TrajOptSolver(problem, "hermite_simpson", compile="wait")
    expected = first.solve(beta=0.5)

    def underived(*_: object) -> None:
        raise AssertionError("the cached path kernels were derived again")

    monkeypatch.setattr(solver_module, "path_kernels", underived)
    second = TrajOptSolver(problem, "hermite_simpson", compile="wait")
    again = second.solve(beta=0.5)
    assert again.status.success == expected.status.success
    assert again.objective == pytest.approx(expected.objective, rel=1e-12)
    moved = dataclasses.replace(problem.clearance, margin=0.02)  # a bound, not the Function
    TrajOptSolver(dataclasses.replace(problem, clearance=moved), "hermite_simpson")
    farther = Obstacle(name="ball", shape=Sphere(radius=0.03), xyz=(0.0, 0.5, 0.9))
    other = dataclasses.replace(problem.clearance, scene=Scene((farther,)))
    with pytest.raises(AssertionError, match="derived again"):
        TrajOptSolver(dataclasses.replace(problem, clearance=other), "hermite_simpson")
