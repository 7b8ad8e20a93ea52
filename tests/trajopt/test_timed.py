"""Tests of the timed trajectory through waypoints (trajopt.timed, #30 item 3).

The planar youBot (the study arm) from the study-1 start to its goal through
two waypoints: the solution passes through them (joint values and Pinocchio's
forward kinematics of the tool frame), T is the sum of the segment durations,
the independent check and the forward-simulation certificate pass. The
comparison with the single-segment NLP is exact by construction: its uniform
solution, split at its middle knot, is a feasible point of the two-segment NLP
whose waypoint is that knot, so the two-segment optimum cannot be worse.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from youbot_opt.exceptions import ParameterError
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.trajopt.certify import certify
from youbot_opt.trajopt.refine import RefinementBudget
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.timed import TimedSolver, solve_through
from youbot_opt.trajopt.waypoints import Waypoints

WAYPOINTS = np.array([[0.3, -0.2, 0.5], [-0.2, 0.4, 0.9]])  # [rad], inside the youBot's limits


@pytest.fixture(scope="module")
def problem(youbot):
    return study1_problem(robot=youbot)


@pytest.fixture(scope="module")
def timed(problem):
    return solve_through(problem, Waypoints(q=WAYPOINTS), beta=0.5)


def _tool_position(robot, q):
    model = robot.model
    data = model.createData()
    frame = model.nframes - 1
    pin.framesForwardKinematics(model, data, np.asarray(q, dtype=float))
    return np.array(data.oMf[frame].translation)


def test_passes_through_the_waypoints(timed, problem):
    assert timed.success, timed.result.message
    traj = timed.result.trajectory
    tol = timed.result.feasibility_tol
    # strictly increasing times, inside (0, T): the waypoints are reached in order
    times = timed.waypoint_times
    assert 0.0 < times[0] < times[1] < timed.duration
    for t, w in zip(times, WAYPOINTS, strict=True):
        q = traj(np.array([t]))[0]
        np.testing.assert_allclose(q, w, rtol=0, atol=tol)
        # the tool frame is where the waypoint puts it (1 mm per rad of arm is generous)
        np.testing.assert_allclose(
            _tool_position(problem.robot, q), _tool_position(problem.robot, w), atol=1e-6
        )
    assert timed.waypoint_error <= tol
    # rest at both ends, and the end is the problem's goal
    np.testing.assert_allclose(traj.v[[0, -1]], 0.0, atol=tol)
    np.testing.assert_allclose(traj.q[-1], problem.goal.q, atol=tol)
    # the velocity at a waypoint is free: the arm does not stop there
    k = timed.waypoint_knots[0]
    assert np.max(np.abs(traj.v[k])) > 0.1


def test_duration_is_the_sum_of_segments(timed):
    segments = timed.segment_durations
    assert segments.shape == (3,) and np.all(segments > 0.0)
    assert timed.duration == pytest.approx(segments.sum(), rel=1e-12)
    np.testing.assert_allclose(timed.waypoint_times, np.cumsum(segments)[:2], rtol=1e-12)
    r = timed.result
    assert r.objective == pytest.approx(0.5 * r.duration + 0.5 * r.work, rel=1e-12)
    # its own grid: one step per segment, 19 intervals a segment
    steps = np.diff(r.trajectory.t)
    np.testing.assert_allclose(steps, np.repeat(segments / 19, 19), rtol=1e-9)


def test_certificate_passes(timed):
    cert = certify(timed.result)
    assert cert.ok, cert.failures()


def test_closed_cycle_returns_to_the_first_waypoint(problem):
    closed = solve_through(problem, Waypoints(q=WAYPOINTS, closed=True), knots_per_segment=8)
    assert closed.success, closed.result.message
    traj = closed.result.trajectory
    np.testing.assert_allclose(traj.q[-1], WAYPOINTS[0], atol=closed.result.feasibility_tol)
    assert closed.result.goal.q.tolist() == WAYPOINTS[0].tolist()
    assert closed.segment_durations.shape == (3,)


def test_first_waypoint_equal_to_the_start_is_the_start(problem):
    w = Waypoints(q=[problem.start.q, WAYPOINTS[0]], closed=True)
    timed = solve_through(problem, w, knots_per_segment=8)
    assert timed.success, timed.result.message
    assert timed.waypoint_knots == (0, 7) and timed.waypoint_times[0] == 0.0
    assert timed.segment_durations.shape == (2,)


def test_a_waypoint_on_the_optimal_path_costs_nothing(youbot):
    """The single-segment optimum split at its middle knot is feasible for two segments."""
    single = TrajOptSolver(study1_problem(21, robot=youbot), "hermite_simpson").solve(beta=0.9)
    assert single.success
    middle = single.variables["q"][10]
    timed = solve_through(
        study1_problem(robot=youbot), Waypoints(q=[middle]), knots_per_segment=11, beta=0.9
    )
    assert timed.success
    # no worse (up to IPOPT's tolerance, 1e-8 relative on the objective), and not by much
    assert timed.result.objective <= single.objective * (1 + 1e-6)
    assert timed.result.objective >= 0.9 * single.objective
    # a detour through a far configuration does cost time
    detour = solve_through(
        study1_problem(robot=youbot), Waypoints(q=[[1.4, -1.5, -1.5]]), knots_per_segment=11,
        beta=0.9,
    )  # fmt: skip
    assert detour.success
    assert detour.duration > 1.2 * single.duration


def test_trapezoidal_through_waypoints(problem):
    timed = solve_through(problem, Waypoints(q=WAYPOINTS), method="trapezoidal")
    assert timed.success, timed.result.message
    assert timed.result.method == "trapezoidal"
    assert timed.waypoint_error <= timed.result.feasibility_tol


def test_errors_name_the_bad_value(problem):
    fixed = dataclasses.replace(problem, duration=3.0)
    with pytest.raises(ParameterError, match="fixed duration = 3.0 s"):
        TimedSolver(fixed, Waypoints(q=WAYPOINTS))
    with pytest.raises(ParameterError, match="'radau'"):
        TimedSolver(problem, Waypoints(q=WAYPOINTS), "radau")
    with pytest.raises(ParameterError, match="knots_per_segment must be an int >= 2, got 1"):
        TimedSolver(problem, Waypoints(q=WAYPOINTS), knots_per_segment=1)
    with pytest.raises(ParameterError, match=r"must have 3 columns"):
        TimedSolver(problem, Waypoints(q=[[0.0, 0.0]]))
    with pytest.raises(ParameterError, match=r"waypoint row 2: q\[1\] = 9 rad is outside"):
        TimedSolver(problem, Waypoints(q=[[0.0, 0.0, 0.0], [0.0, 9.0, 0.0]]))
    with pytest.raises(ParameterError, match="nothing to time"):
        TimedSolver(problem, Waypoints(q=[problem.start.q], closed=True))


def test_one_segment_is_the_point_to_point_solve(youbot):
    """A first waypoint equal to the start leaves one segment: the plain NLP, the same guess."""
    plain = TrajOptSolver(study1_problem(20, robot=youbot), "hermite_simpson").solve(beta=0.5)
    problem = study1_problem(robot=youbot)
    timed = solve_through(problem, Waypoints(q=[problem.start.q]), knots_per_segment=20)
    assert plain.success and timed.success
    assert timed.segment_durations.shape == (1,) and timed.waypoint_times.tolist() == [0.0]
    # same NLP up to the order of operations, same start: IPOPT's tolerance apart
    assert timed.result.objective == pytest.approx(plain.objective, rel=1e-7)
    assert timed.duration == pytest.approx(plain.duration, rel=1e-6)


def test_refine_through_waypoints_keeps_them_pinned(problem):
    """Refinement splits intervals within their segments: the waypoint knots stay segment ends.

    The study arm through three waypoints at beta = 1 (benchmarks/bench_timed.py's
    youBot case): certified on 20 knots a segment, its largest interval error
    2e-3 over the 1e-3 tolerance; refined, certified again, T moves by < 1 %.
    """
    w = np.vstack([WAYPOINTS, [0.5, 0.8, -0.4]])
    solver = TimedSolver(problem, Waypoints(q=w))
    first = solver.solve(beta=1.0)
    assert first.success, first.result.message
    assert certify(first.result).ok
    refined = solver.refine(first=first, budget=RefinementBudget(max_rounds=4))
    record = refined.refinement
    assert record is not None and record.rounds[0].n_knots == 77
    assert record.rounds[0].max_error > record.budget.tolerance
    assert refined.certified and record.reason == "certified", record.reason
    assert record.rounds[-1].n_knots > 77  # it did split
    assert record.rounds[-1].max_error <= record.budget.tolerance
    r = refined.result
    assert r.success and r.problem.n_knots == record.rounds[-1].n_knots
    assert refined.duration == pytest.approx(first.duration, rel=0.01)
    # every waypoint still hit, exactly at its knot, a segment end
    assert refined.waypoint_error <= r.feasibility_tol
    q = r.variables["q"]
    for k, row in zip(refined.waypoint_knots, w, strict=True):
        np.testing.assert_allclose(q[k], row, rtol=0, atol=r.feasibility_tol)
    t = r.trajectory.t
    np.testing.assert_allclose(refined.waypoint_times, t[list(refined.waypoint_knots)])
    np.testing.assert_allclose(
        np.cumsum(refined.segment_durations)[:-1], refined.waypoint_times, rtol=1e-12
    )
    assert refined.duration == pytest.approx(refined.segment_durations.sum(), rel=1e-12)
    summary = refined.summary()
    assert summary["refinement"]["reason"] == "certified"
    assert [x["n_knots"] for x in summary["refinement"]["rounds"]] == [
        x.n_knots for x in record.rounds
    ]
    assert first.refinement is None and not first.certified


UR5_START = np.array([0.0, -1.2, 1.0, -0.5, 0.3, 0.0])  # [rad]
UR5_OTHER = np.array([0.8, -0.6, 0.4, -1.2, -0.3, 0.5])  # [rad]


@pytest.fixture(scope="module")
def ur5_cycle():
    """The UR5 closed cycle of docs/timed.md at beta = 1: its solver and its 39-knot plan."""
    from youbot_opt.robot.load import load_model
    from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem

    state = BoundaryState(q=UR5_START)
    problem = TrajOptProblem(robot=load_model("ur5"), start=state, goal=state)
    solver = TimedSolver(problem, Waypoints(q=[UR5_START, UR5_OTHER], closed=True))
    first = solver.solve(beta=1.0)
    assert first.success, first.result.message  # no false violation of the 150 N m bounds
    return solver, first


def _check_cycle(refined):
    assert refined.waypoint_knots[0] == 0 and refined.waypoint_times[0] == 0.0
    assert refined.waypoint_error <= refined.result.feasibility_tol
    assert refined.result.variables["q"][-1] == pytest.approx(UR5_START, abs=1e-6)


def test_refine_through_waypoints_says_why_it_cannot_certify(ur5_cycle):
    """The UR5 closed cycle at beta = 1 (docs/timed.md): a torque switches bang-bang in an interval.

    Hermite-Simpson's quadratic torque through 150, 150, -150 N m peaks 25 % over
    the bound however short the interval, so splitting cannot certify it: without
    the trapezoidal fallback the record says which check failed, round by round,
    the next step names the trapezoidal scheme, and the waypoints stay hit.
    """
    from youbot_opt.cli.advice import next_step

    solver, first = ur5_cycle
    budget = RefinementBudget(max_rounds=2, fallback=False)
    refined = solver.refine(first=first, budget=budget)
    record = refined.refinement
    assert refined.success and not refined.certified
    assert [r.certificate_passed for r in record.rounds] == [False, False]
    assert [r.method for r in record.rounds] == ["hermite_simpson"] * 2
    assert record.rounds[1].n_knots > record.rounds[0].n_knots == 39
    assert "bound torque, between knots" in record.reason and "after 2 rounds" in record.reason
    assert "torque switches between its bounds inside an interval" in record.reason
    assert "trapezoidal" in record.reason and "no trapezoidal fallback" in record.reason
    step = next_step(refined.result, record)
    assert step.startswith("--transcription trapezoidal (joint ")
    assert "% of the half range, up to 25 % on any grid)" in step
    _check_cycle(refined)


def test_refine_through_waypoints_falls_back_to_the_trapezoid(ur5_cycle):
    """By default the overshoot switches the refinement to the trapezoid on the same knots.

    Round 1 re-solves the 39-knot grid with the trapezoidal scheme from round
    0's plan; its error then drives the splits (the segments and pinned
    waypoints kept). Two rounds leave it uncertified on its error, and the next
    step is more rounds (the trapezoid's error has not yet been split).
    """
    from youbot_opt.cli.advice import next_step
    from youbot_opt.cli.refinement import refinement_table

    solver, first = ur5_cycle
    refined = solver.refine(first=first, budget=RefinementBudget(max_rounds=2))
    record = refined.refinement
    assert [r.method for r in record.rounds] == ["hermite_simpson", "trapezoidal"]
    assert [r.n_knots for r in record.rounds] == [39, 39]
    assert refined.success and not refined.certified
    assert refined.result.method == "trapezoidal"
    assert (
        record.reason.startswith("not certified: max error ") and "after 2 rounds" in record.reason
    )
    assert "switches between its bounds" not in record.reason  # the trapezoid cannot overshoot
    assert next_step(refined.result, record).startswith("--max-rounds 4")
    table = "\n".join(refinement_table(refined.result, record))
    assert "scheme        hermite_simpson -> trapezoidal from round 1" in table
    assert [x["method"] for x in refined.summary()["refinement"]["rounds"]] == [
        "hermite_simpson",
        "trapezoidal",
    ]
    _check_cycle(refined)


@pytest.mark.slow
def test_refine_through_waypoints_certifies_the_ur5_cycle_with_the_fallback(ur5_cycle):
    """The default budget certifies the cycle (measured 39 HS, 39, 444, 471 trapezoidal knots)."""
    solver, first = ur5_cycle
    refined = solver.refine(first=first)
    record = refined.refinement
    assert refined.certified, record.reason
    assert record.rounds[0].method == "hermite_simpson"
    assert {r.method for r in record.rounds[1:]} == {"trapezoidal"}
    assert record.rounds[-1].certificate_passed and record.rounds[-1].max_error <= 1e-3
    _check_cycle(refined)
