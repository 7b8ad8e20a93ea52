"""Property tests of the trajectory API: a status that matches an independent check, or an error.

Hypothesis draws valid and invalid inputs (boundary states inside and outside
the bounds, ``beta`` in and out of [0, 1], 0..40 knots, ``bound_scale <= 0``,
wrong shapes, NaN/inf, tiny iteration and CPU-time caps). Every call must
either raise a documented :class:`~youbot_opt.exceptions.YoubotOptError` or
return a result whose status survives checks written out in this file
(finiteness, bounds, boundary states, collocation defects with ``pin.aba``,
the reported T, W, f), not :func:`~youbot_opt.trajopt.result.check_result`: a success
passes all of them, a failure fails one or carries IPOPT's failure flag. Runs are
derandomized and database-free, so CI sees the same examples every time.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from youbot_opt.exceptions import ParameterError, SolveFailed
from youbot_opt.nlp.ipopt import IpoptOptions
from youbot_opt.robot.load import load_model
from youbot_opt.trajopt.certify import check_bounds
from youbot_opt.trajopt.check import check_result, checked
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.result import SolveStatus, TrajOptResult
from youbot_opt.trajopt.solver import TrajOptSolver

PROPERTY = settings(
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

# Solver builds cost 0.1-1.5 s, so the solvers are cached per (knots, method, options).
_SOLVERS: dict[tuple[Any, ...], TrajOptSolver] = {}

# Guard against hangs only (no timing claim): a capped solve must stop within
# 10x its CPU-time cap plus 2 s for the checks and the process's other work.
HANG_FACTOR, HANG_MARGIN = 10.0, 2.0  # [-], [s]


@pytest.fixture(scope="module")
def youbot():
    """The planar youBot with the study code's joint damping."""
    return load_model("youbot", damping=0.1)


def _solver(problem: TrajOptProblem, method: str, options: IpoptOptions) -> TrajOptSolver:
    key = (problem.n_knots, method, options.max_iter, options.max_cpu_time, problem.duration)
    key += (problem.start.q.tobytes(), problem.goal.q.tobytes())
    if key not in _SOLVERS:
        _SOLVERS[key] = TrajOptSolver(problem, method, options)
    return _SOLVERS[key]


_SPECIAL = st.sampled_from([math.nan, math.inf, -math.inf])
_FRACTIONS = st.lists(st.floats(-0.9, 0.9), min_size=3, max_size=3)


def _inside(robot: Any, fractions: list[float]) -> list[float]:
    """q at ``fractions`` (in [-1, 1]) of the half range about the middle of the limits."""
    lo, hi = np.asarray(robot.q_lower), np.asarray(robot.q_upper)
    return list(0.5 * (lo + hi) + 0.5 * (hi - lo) * np.asarray(fractions))


def _call(robot: Any, n_knots: Any, method: str, inputs: dict[str, Any]) -> TrajOptResult:
    """Build options, problem and (cached) solver, then solve: the whole public path."""
    opts = IpoptOptions(max_iter=inputs["max_iter"], max_cpu_time=inputs["max_cpu_time"])
    problem = TrajOptProblem(
        robot=robot,
        start=BoundaryState(q=inputs["start"]),
        goal=BoundaryState(q=inputs["goal"]),
        n_knots=n_knots,
        duration=inputs["duration"],
    )
    solver = _solver(problem, method, opts)
    return solver.solve(beta=inputs["beta"], bound_scale=inputs["bound_scale"])


@settings(PROPERTY, max_examples=25)
@given(
    n_knots=st.integers(2, 40),
    method=st.sampled_from(["trapezoidal", "hermite_simpson"]),
    start=_FRACTIONS,
    goal=_FRACTIONS,
    beta=st.floats(0.0, 1.0),
    bound_scale=st.floats(0.5, 1.2),
    max_iter=st.sampled_from([0, 1, 5, 300, 300]),
    max_cpu_time=st.sampled_from([None, 1e-3, 0.5, 1.0]),
    duration=st.one_of(st.none(), st.floats(0.5, 3.0)),
)
def test_valid_inputs_status_matches_independent_check(
    youbot, n_knots, method, start, goal, beta, bound_scale, max_iter, max_cpu_time, duration
) -> None:
    """Valid inputs never raise; the status agrees with checks independent of check_result."""
    # Boundary states inside the scaled bounds (position bounds scale about zero).
    shrink = min(bound_scale, 1.0)
    inputs = dict(
        start=shrink * np.array(_inside(youbot, start)),
        goal=shrink * np.array(_inside(youbot, goal)),
        beta=beta, bound_scale=bound_scale, max_iter=max_iter, max_cpu_time=max_cpu_time,
        duration=duration,
    )  # fmt: skip
    tic = time.process_time()
    result = _call(youbot, n_knots, method, inputs)
    event(f"returned {result.status.value}")
    _assert_honest(result)
    assert result.iterations <= max_iter
    if max_cpu_time is not None:  # hang guard only, see HANG_FACTOR
        limit = HANG_FACTOR * max_cpu_time + HANG_MARGIN
        assert result.cpu_time <= limit
        assert time.process_time() - tic <= limit + 2.0  # + a possible solver build


_VALID = dict(
    start=[-0.5, -0.5, -1.0], goal=[0.5, 0.5, 1.0], beta=0.5, bound_scale=1.0,
    max_iter=3, max_cpu_time=None, duration=None,
)  # fmt: skip
_INVALID: dict[str, st.SearchStrategy[Any]] = {
    "n_knots": st.sampled_from([0, 1, -3, 2.5, True, "50", None]),
    "beta": st.one_of(
        st.floats(1.0, 10.0, exclude_min=True), st.floats(-10.0, 0.0, exclude_max=True), _SPECIAL
    ),
    "bound_scale": st.one_of(st.floats(-10.0, 0.0), _SPECIAL, st.just(None)),
    "start": st.one_of(
        st.tuples(_SPECIAL, st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)).map(list),
        st.lists(st.floats(-0.5, 0.5), max_size=6).filter(lambda v: len(v) != 3),
        st.tuples(st.floats(3.5, 1e6), st.just(0.0), st.just(0.0)).map(list),
        st.just([[0.0, 0.0, 0.0]]),
    ),
    "goal": st.one_of(
        st.tuples(st.floats(-0.5, 0.5), _SPECIAL, st.floats(-0.5, 0.5)).map(list),
        st.tuples(st.just(0.0), st.just(0.0), st.floats(-1e6, -5.0)).map(list),
        st.just("up"),
    ),
    "max_iter": st.sampled_from([-1, 2.5, None, True]),
    "max_cpu_time": st.one_of(st.floats(-10.0, 0.0), _SPECIAL),
    "duration": st.one_of(st.floats(-10.0, 0.0), _SPECIAL),
}


@settings(PROPERTY, max_examples=60)
@given(
    field=st.sampled_from(sorted(_INVALID)),
    data=st.data(),
    method=st.sampled_from(["trapezoidal", "hermite_simpson"]),
)
def test_one_invalid_input_raises_parameter_error(youbot, field, data, method) -> None:
    """Exactly one invalid input (NaN/inf, sign, range, shape, type) raises ParameterError."""
    value = data.draw(_INVALID[field], label=field)
    inputs = dict(_VALID)
    n_knots: Any = 4
    if field == "n_knots":
        n_knots = value
    else:
        inputs[field] = value
    with pytest.raises(ParameterError) as info:
        _call(youbot, n_knots, method, inputs)
    assert str(info.value)


def _independent_violations(result: TrajOptResult) -> list[str]:
    """What is wrong with a result, found without check_result or the NLP.

    Finiteness, scaled bounds at the knots, the boundary states, the
    collocation defects with accelerations from ``pin.aba`` (damping applied
    as ``tau - b v``) and the reported T, W, f recomputed here. Tolerance:
    ``result.feasibility_tol`` (1e-6) for every row -- IPOPT meets its rows to
    ~1e-8 (``tol``) and relaxes bounds by 1e-8 relative -- and 1e-9 relative
    for the reported figures (summation order only).
    """
    import pinocchio as pin

    problem, tol = result.problem, result.feasibility_tol
    var = {k: np.asarray(x, dtype=float) for k, x in result.variables.items()}
    figures = (result.objective, result.duration, result.work, result.dt)
    if not all(np.all(np.isfinite(x)) for x in var.values()) or not np.all(np.isfinite(figures)):
        return ["non-finite"]
    q, v, tau, dt = var["q"], var["v"], var["tau"], float(var["dt"][0, 0])
    bad = []
    b = result.bounds()
    for name, x, lo, hi in (("q", q, b.q_lower, b.q_upper), ("v", v, b.v_lower, b.v_upper),
                            ("tau", tau, b.tau_lower, b.tau_upper)):  # fmt: skip
        if np.any(x < lo - tol) or np.any(x > hi + tol):
            bad.append(f"{name} bound")
    n = problem.n_knots
    dt_lo, dt_hi = problem.dt_min, problem.dt_max
    if problem.duration is not None:
        dt_lo = dt_hi = problem.duration / (n - 1)
    if not (dt > 0 and dt_lo - tol <= dt <= dt_hi + tol):
        bad.append(f"dt = {dt}")
    for name, x, want in (("start q", q[0], result.start.q), ("goal q", q[-1], result.goal.q),
                          ("start v", v[0], result.start.velocity),
                          ("goal v", v[-1], result.goal.velocity)):  # fmt: skip
        if np.max(np.abs(x - want)) > tol:
            bad.append(name)
    model = problem.robot.model
    data = model.createData()
    damping = np.asarray(problem.robot.damping, dtype=float) if problem.damping else 0.0

    def aba(qs, vs, taus):
        return np.array([pin.aba(model, data, qk, vk, tk - damping * vk)
                         for qk, vk, tk in zip(qs, vs, taus, strict=True)])  # fmt: skip

    a = aba(q, v, tau)
    power = np.sum(tau**2, axis=1)
    if result.method == "hermite_simpson":
        qm, vm = var["q_mid"], var["v_mid"]
        am = aba(qm, vm, var["tau_mid"])
        defects = [
            q[1:] - q[:-1] - dt / 6 * (v[:-1] + 4 * vm + v[1:]),
            v[1:] - v[:-1] - dt / 6 * (a[:-1] + 4 * am + a[1:]),
            qm - (q[:-1] + q[1:]) / 2 - dt / 8 * (v[:-1] - v[1:]),
            vm - (v[:-1] + v[1:]) / 2 - dt / 8 * (a[:-1] - a[1:]),
        ]
        work = dt / 6 * np.sum(power[:-1] + 4 * np.sum(var["tau_mid"] ** 2, axis=1) + power[1:])
    else:
        defects = [q[1:] - q[:-1] - dt / 2 * (v[:-1] + v[1:]),
                   v[1:] - v[:-1] - dt / 2 * (a[:-1] + a[1:])]  # fmt: skip
        work = dt / 2 * np.sum(power[:-1] + power[1:])
    if max(float(np.max(np.abs(d), initial=0.0)) for d in defects) > tol:
        bad.append("collocation defect")
    objective = result.beta * (n - 1) * dt + (1 - result.beta) * work
    for name, got, want in (("T", result.duration, (n - 1) * dt), ("W", result.work, work),
                            ("f", result.objective, objective)):  # fmt: skip
        if abs(got - want) > 1e-9 * max(1.0, abs(want)):
            bad.append(f"reported {name}")
    return bad


_CONVERGED = {"Solve_Succeeded": SolveStatus.SOLVED,
              "Solved_To_Acceptable_Level": SolveStatus.SOLVED_ACCEPTABLE}  # fmt: skip


def _assert_honest(result: TrajOptResult) -> None:
    """A success passes every independent check; a failure has a failed check or a failed flag."""
    bad = _independent_violations(result)
    if result.success:
        assert not bad, (result.status, bad)
        assert result.status is _CONVERGED[result.solver_status]
        # And on the Trajectory (not the NLP vector), by the certificate's bound check.
        assert result.trajectory is not None
        for c in check_bounds(result.trajectory, result.bounds()):
            if c.where == "knots":
                assert c.excess <= result.feasibility_tol, c
    else:
        assert bad or result.solver_status not in _CONVERGED, (result.status, result.message)
        assert result.message
        with pytest.raises(SolveFailed) as info:
            result.raise_for_status()
        assert info.value.result is result
        # The best iterate is returned with every block of the right shape.
        assert result.variables["q"].shape == (result.problem.n_knots, result.problem.nv)


# --------------------------------------------------------------------- corrupted results
@pytest.fixture(scope="module")
def solved(youbot) -> dict[str, TrajOptResult]:
    """A converged 12-knot study-1 solve per transcription."""
    out = {}
    for method in ("trapezoidal", "hermite_simpson"):
        problem = TrajOptProblem(
            robot=youbot,
            start=BoundaryState(q=[-math.pi / 6, -math.pi / 6, -math.pi / 3]),
            goal=BoundaryState(q=[math.pi / 6, math.pi / 6, math.pi / 3]),
            n_knots=12,
        )
        out[method] = TrajOptSolver(problem, method).solve(beta=0.5).raise_for_status()
    return out


@settings(PROPERTY, max_examples=80)
@given(
    method=st.sampled_from(["trapezoidal", "hermite_simpson"]),
    block=st.sampled_from(["q", "v", "tau", "dt", "q_mid", "v_mid", "tau_mid"]),
    where=st.floats(0.0, 1.0, exclude_max=True),
    joint=st.integers(0, 2),
    corruption=st.one_of(_SPECIAL, st.floats(1e-4, 10.0), st.floats(-10.0, -1e-4)),
)
def test_corrupted_solution_is_never_a_success(
    solved, method, block, where, joint, corruption
) -> None:
    """NaN/inf or a perturbation > 1e-4 in any variable turns a success into a failure."""
    good = solved[method]
    if block not in good.variables:
        block = "q"
    arr = np.array(good.variables[block])
    k = int(where * arr.shape[0])
    j = min(joint, arr.shape[1] - 1)
    arr[k, j] = corruption if not math.isfinite(corruption) else arr[k, j] + corruption
    bad = checked(dataclasses.replace(good, variables={**good.variables, block: arr}))
    check = check_result(bad)
    assert not check.passed and not bad.success
    assert _independent_violations(bad)  # and this file's own checks see it too
    assert bad.status is check.status
    expected = SolveStatus.NON_FINITE if not math.isfinite(corruption) else None
    if expected is not None:
        assert bad.status is expected
    with pytest.raises(SolveFailed, match=bad.status.value):
        bad.raise_for_status()
