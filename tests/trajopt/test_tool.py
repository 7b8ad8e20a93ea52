"""Tool constraints in trajectory optimisation (#30 item 2): the youBot's planar arm.

Known answers: the study arm's swing from (-30, -30, 60) to (30, 30, -60) degrees
starts and ends with the gripper's x axis straight up but tilts it by 0.057 rad on
the way; kept within 0.03 rad, every transcription's plan holds it at the knots
(a little above between them: the certificate finds it, refinement fixes it) at a
cost no lower than the free one. The free plan's tool peaks at 0.46 m/s; held to
0.3 m/s the motion takes longer.
"""

from __future__ import annotations

import dataclasses
import pickle

import casadi as ca
import numpy as np
import pytest

from youbot_opt.exceptions import FrameNotFound, ParameterError
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import frame_placement
from youbot_opt.trajopt.certify import certify
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.refine import refine
from youbot_opt.trajopt.solver import TrajOptSolver
from youbot_opt.trajopt.tool import (
    KeepAxis,
    NearLine,
    ToolConstraint,
    ToolSpeed,
    tool_constraint,
    tool_from_document,
    tool_measures,
)
from youbot_opt.trajopt.tool_certificate import certify_plan_tool

METHODS = ("trapezoidal", "hermite_simpson", "radau")
TILT = 0.03  # [rad]
SPEED = 0.3  # [m/s]


@pytest.fixture(scope="module")
def free() -> TrajOptProblem:
    """The swing on 20 knots, no tool constraint."""
    q = np.deg2rad([-30.0, -30.0, 60.0])
    return TrajOptProblem(
        robot=load_model("youbot"),
        start=BoundaryState(q=q),
        goal=BoundaryState(q=-q),
        n_knots=20,
    )


def _upright(problem: TrajOptProblem, limit: float = TILT) -> KeepAxis:
    """The gripper's x axis kept near its start direction (world up)."""
    up = frame_placement(problem.robot, problem.start.q).rotation[:, 0]
    return KeepAxis(axis=(1.0, 0.0, 0.0), direction=up, max_angle=limit)


def _along(result, constraint, n: int = 401) -> np.ndarray:
    """The measure along the plan at ``n`` times."""
    traj = result.trajectory
    t = np.linspace(0.0, result.duration, n)
    q = np.array([traj(x) for x in t])
    v = np.array([traj.velocity(x) for x in t])
    return tool_measures(result.problem.robot, (constraint,), q, v)[:, 0]


@pytest.fixture(scope="module")
def free_results(free: TrajOptProblem) -> dict:
    """The free optimum of each transcription."""
    return {m: TrajOptSolver(free, m).solve(beta=0.5) for m in METHODS}


def test_no_tool_no_rows(free: TrajOptProblem) -> None:
    """Without tool constraints the NLP has no tool block."""
    assert tool_constraint(free.robot, ()) is None
    assert not any(name.startswith("tool") for name in TrajOptSolver(free).nlp.constraints.blocks)


@pytest.mark.parametrize("method", METHODS)
def test_cup_kept_upright(free: TrajOptProblem, free_results: dict, method: str) -> None:
    """The free optimum tilts beyond the limit; the constrained plan keeps it, certified."""
    unconstrained = free_results[method]
    upright = _upright(free)
    assert unconstrained.success and _along(unconstrained, upright).max() > 1.5 * TILT
    problem = dataclasses.replace(free, tool=(upright,))
    solver = TrajOptSolver(problem, method)
    assert any(name.startswith("tool") for name in solver.nlp.constraints.blocks)
    result, refinement = refine(solver, beta=0.5)
    assert result.success and refinement.certified, refinement.reason
    q, v = result.variables["q"], result.variables["v"]
    knots = tool_measures(problem.robot, (upright,), q, v)[:, 0]
    assert knots.max() <= TILT + upright.slack(1e-6)
    assert _along(result, upright).max() <= TILT * (1 + 1e-3)
    # on the same 20 knots the constraint costs: f >= the free f
    assert refinement.rounds[0].objective >= unconstrained.objective - 1e-9
    # round 0 held the knots but not everything between them: found, then fixed
    assert any("keep axis" in f for f in refinement.rounds[0].failures)
    assert refinement.certificate is not None and refinement.certificate.tool[0].certified


@pytest.mark.parametrize("method", METHODS)
def test_tool_speed_limit_lengthens_the_motion(
    free: TrajOptProblem, free_results: dict, method: str
) -> None:
    """A speed limit below the free peak: a longer motion, the tool under the limit."""
    unconstrained = free_results[method]
    limit = ToolSpeed(max_speed=SPEED)
    assert _along(unconstrained, limit).max() > 1.3 * SPEED
    problem = dataclasses.replace(free, tool=(limit,))
    result, refinement = refine(TrajOptSolver(problem, method), beta=0.5)
    assert result.success and refinement.certified, refinement.reason
    assert result.duration > unconstrained.duration * 1.05
    assert _along(result, limit).max() <= SPEED * (1 + 1e-3)


def test_tool_on_a_line(free: TrajOptProblem) -> None:
    """The tool point kept within 5 mm of the straight segment between its end positions."""
    p0 = frame_placement(free.robot, free.start.q).translation
    p1 = frame_placement(free.robot, free.goal.q).translation
    weld = NearLine(p0=p0, p1=p1, tolerance=0.005)
    problem = dataclasses.replace(free, tool=(weld,))
    result, refinement = refine(TrajOptSolver(problem, "hermite_simpson"), beta=0.5)
    assert result.success and refinement.certified, refinement.reason
    assert _along(result, weld).max() <= 0.005 * (1 + 1e-3)


def test_knot_only_violation_caught_between_knots(free: TrajOptProblem) -> None:
    """Knots inside the limit, the motion between them outside: not certified, named."""
    upright = _upright(free)
    result = TrajOptSolver(dataclasses.replace(free, tool=(upright,)), "trapezoidal").solve()
    q, v = result.variables["q"], result.variables["v"]
    assert tool_measures(free.robot, (upright,), q, v).max() <= TILT + upright.slack(1e-6)
    (cert,) = certify_plan_tool(result.trajectory, result.problem.robot, (upright,))
    assert not cert.certified and cert.worst_value > TILT * (1 + 1e-3)
    assert cert.failures and "keep axis" in cert.describe()
    # the trajectory certificate lists it among its checks
    full = certify(result)
    assert not full.ok and any(f.startswith("tool: keep axis [rad]") for f in full.failures())
    assert full.summary()["tool"][0]["certified"] is False


def _rows(problem: TrajOptProblem, constraints) -> tuple:
    fn = tool_constraint(problem.robot, constraints).function
    return fn, problem.nv


@pytest.mark.parametrize("where", ["inside", "before p0", "after p1"])
def test_row_gradients_match_central_differences(free: TrajOptProblem, where: str) -> None:
    """d c / d(q, v) of every kind's row against central differences (1e-6)."""
    p = frame_placement(free.robot, free.start.q).translation
    shift = {"inside": 0.5, "before p0": -0.3, "after p1": 1.4}[where]
    seg = np.array([0.0, 0.0, 0.2])
    constraints = (
        _upright(free),
        NearLine(p0=p - shift * seg, p1=p - shift * seg + seg, tolerance=0.01),
        ToolSpeed(max_speed=0.5),
    )
    fn, nv = _rows(free, constraints)
    rng = np.random.default_rng(3)
    q = free.start.q + 0.1 * rng.standard_normal(nv)
    v = rng.standard_normal(nv)
    qs, vs = ca.SX.sym("q", nv), ca.SX.sym("v", nv)
    jac = ca.Function("j", [qs, vs], [ca.jacobian(fn(qs, vs), ca.vertcat(qs, vs))])
    analytic = np.asarray(jac(q, v))
    x = np.concatenate([q, v])
    step = 1e-6
    numeric = np.empty_like(analytic)
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = step
        hi = np.asarray(fn((x + e)[:nv], (x + e)[nv:])).ravel()
        lo = np.asarray(fn((x - e)[:nv], (x - e)[nv:])).ravel()
        numeric[:, i] = (hi - lo) / (2 * step)
    np.testing.assert_allclose(analytic, numeric, atol=1e-6, rtol=1e-6)


def test_rows_agree_with_the_measures(free: TrajOptProblem) -> None:
    """The NLP's CasADi rows and Pinocchio's measures describe the same quantities."""
    upright, weld, limit = (
        _upright(free),
        NearLine(p0=(0.0, 0.0, 0.5), p1=(0.2, 0.0, 0.5), tolerance=0.02),
        ToolSpeed(max_speed=0.4),
    )
    fn, nv = _rows(free, (upright, weld, limit))
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, v = rng.uniform(-1, 1, nv), rng.uniform(-1, 1, nv)
        c = np.asarray(fn(q, v)).ravel()
        m = tool_measures(free.robot, (upright, weld, limit), q, v)[0]
        np.testing.assert_allclose(
            [np.arccos(np.clip(c[0], -1, 1)), np.sqrt(c[1]) * 0.02, np.sqrt(c[2]) * 0.4],
            m,
            atol=1e-7,
        )


def test_start_breaking_a_constraint_refused(free: TrajOptProblem) -> None:
    """A start tilted beyond the limit is refused before solving, naming the value."""
    tilted = KeepAxis(axis=(1.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0), max_angle=0.1)
    problem = dataclasses.replace(free, tool=(tilted,))
    with pytest.raises(
        ParameterError, match=r"start: keep axis \(gripper_tip\) is 1\.571 rad"
    ) as e:
        TrajOptSolver(problem)
    assert e.value.value == pytest.approx(np.pi / 2)


def test_moving_goal_over_the_speed_limit_refused(free: TrajOptProblem) -> None:
    """A goal velocity whose tool speed exceeds the limit is refused at solve time."""
    problem = dataclasses.replace(free, tool=(ToolSpeed(max_speed=0.05),))
    solver = TrajOptSolver(problem)
    goal = BoundaryState(q=free.goal.q, v=np.full(free.nv, 0.5))
    with pytest.raises(ParameterError, match=r"goal: tool speed .* m/s, above its limit 0\.05"):
        solver.solve(goal=goal)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: KeepAxis(axis=(0, 0, 0), direction=(0, 0, 1), max_angle=0.1), "axis"),
        (lambda: KeepAxis(axis=(1, 0, 0), direction=(0, 0, 1), max_angle=-0.1), "max_angle"),
        (lambda: KeepAxis(axis=(1, 0, 0), direction=(0, 0, 1), max_angle=4.0), "max_angle"),
        (lambda: NearLine(p0=(0, 0), p1=(0, 0, 1), tolerance=0.01), "p0"),
        (lambda: NearLine(p0=(0, 0, 0), p1=(0, 0, 1), tolerance=0.0), "tolerance"),
        (lambda: ToolSpeed(max_speed=float("nan")), "max_speed"),
        (lambda: ToolSpeed(max_speed=1.0, frame=""), "frame"),
        (lambda: ToolConstraint(), "use KeepAxis, NearLine or ToolSpeed"),
    ],
)
def test_bad_constraints_refused(make, match: str) -> None:
    """Constructors refuse bad values, naming the field."""
    with pytest.raises(ParameterError, match=match):
        make()


def test_unknown_frame_refused(free: TrajOptProblem) -> None:
    """A tool frame the robot does not have is refused with the frames listed."""
    with pytest.raises(FrameNotFound):
        dataclasses.replace(free, tool=(ToolSpeed(max_speed=1.0, frame="nope"),))


def test_documents_round_trip(free: TrajOptProblem) -> None:
    """Each kind survives its JSON document; the problem's description lists them."""
    kinds = (
        _upright(free),
        NearLine(p0=(0, 0, 0.5), p1=(0.1, 0, 0.5), tolerance=0.01, frame="gripper_tip"),
        ToolSpeed(max_speed=0.4),
    )
    for c in kinds:
        back = tool_from_document(c.document())
        assert back.document() == c.document() and back == c and hash(back) == hash(c)
        assert pickle.loads(pickle.dumps(c)) == c  # a multistart's workers receive the problem
    assert dataclasses.replace(free, tool=kinds).describe()["tool"][2]["max_speed_m_per_s"] == 0.4
    assert "tool" not in free.describe()
    with pytest.raises(ParameterError, match="unknown tool constraint kind"):
        tool_from_document({"kind": "wobble"})


def test_saved_tool_constraints_rechecked_on_load(free: TrajOptProblem, tmp_path) -> None:
    """The constraints round-trip; a loaded plan is checked against them, not the file."""
    from youbot_opt.trajopt.io import load_result, save_result

    problem = dataclasses.replace(free, tool=(_upright(free),))
    result = TrajOptSolver(problem, "hermite_simpson").solve(beta=0.5)
    assert result.status.success
    assert result.summary()["tool"][0]["largest_at_knots"] <= TILT + 1e-6
    loaded = load_result(save_result(result, tmp_path / "cup"))
    assert loaded.problem.tool == problem.tool and loaded.status.success
    # the same plan under a tighter tilt than it keeps: the check refuses it on load
    tighter = dataclasses.replace(problem, tool=(_upright(free, 0.01),))
    strict = dataclasses.replace(result, problem=tighter)
    reloaded = load_result(save_result(strict, tmp_path / "strict"))
    assert not reloaded.status.success
    assert "keep axis" in reloaded.message and "limit 0.01 rad" in reloaded.message
